"""The results.json sections the report reads typed (``cadfeat.results``: ``PoseAccuracy``, ``Robustness``'s
robust-redesign keys): data as its producer writes it meets the written results schema, and a planted mistake is
refused by the schema and by the model alike.

Independent reference: the ``jsonschema`` library (Draft 2020-12) on ``cadfeat schema --results``'s output, each
section checked against its own definition; ``pose_accuracy`` is computed by ``cadfeat.study.pose_accuracy`` on
the report fixture's re-extracted holes, ``robustness`` is the hand-written block of
``report_fixture.robustness_block``.
"""

from __future__ import annotations

import copy
import json

import jsonschema
import numpy as np
import pydantic
import pytest
from report_fixture import robustness_block, shared_case

from cadfeat.cli import main
from cadfeat.poses import invert_T
from cadfeat.results import PoseAccuracy, Robustness, section
from cadfeat.study.pose_accuracy import PHASES, design_pose_accuracy
from cadfeat.vision import FilterTuning


@pytest.fixture(scope="module")
def schema(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("schema") / "results.schema.json"
    assert main(["schema", "--results", "--out", str(out)]) == 0
    return json.loads(out.read_text())


def _validator(schema: dict, name: str) -> jsonschema.Draft202012Validator:
    """The validator of one top-level section of results.json (its property schema, with the definitions)."""
    return jsonschema.Draft202012Validator({"$defs": schema["$defs"], **schema["properties"][name]})


@pytest.fixture(scope="module")
def pose_block() -> dict:
    _, res, ctx = shared_case()
    T = invert_T(np.asarray(ctx.trajectory.T_task_cam)) @ ctx.T_task_part
    movable = [h.name for h, f in zip(ctx.holes_before, ctx.fixed_mask, strict=True) if not f]
    block = {"times_s": np.asarray(ctx.trajectory.times_s).tolist(), "phases": list(PHASES)}
    for key, holes in (("before", ctx.holes_before), ("after", ctx.holes_after)):
        block[key] = design_pose_accuracy(ctx.camera, T, np.asarray(ctx.trajectory.times_s), holes,
                                          [h.name for h in holes], movable, None, FilterTuning(), 50.0)
    return json.loads(json.dumps(block))  # as results.json holds it


def test_pose_accuracy_meets_the_schema_and_reads_typed(schema, pose_block):
    assert not [e.message for e in _validator(schema, "pose_accuracy").iter_errors(pose_block)]
    typed = section({"pose_accuracy": pose_block}, "pose_accuracy", PoseAccuracy)
    assert typed is not None and typed.to_data() == pose_block
    assert typed.after is not None and typed.after.rms is not None
    assert typed.after.rms.error_translation_mm == pose_block["after"]["rms"]["error_translation_mm"]
    assert [w.phase for w in typed.before.weakest] == [w["phase"] for w in pose_block["before"]["weakest"]]


def test_robust_designs_meet_the_schema_and_read_typed(schema):
    block = json.loads(json.dumps(robustness_block("robust")))
    assert not [e.message for e in _validator(schema, "robustness").iter_errors(block)]
    typed = section({"robustness": block}, "robustness", Robustness)
    assert typed is not None and typed.to_data() == block
    assert typed.out_of_sample is not None
    assert typed.out_of_sample.designs["robust"].out_of_sample == block["out_of_sample"]["designs"]["robust"][
        "out_of_sample"]
    assert typed.designs is not None and typed.designs["original"]["cell"]["combined"].p05 == pytest.approx(-1.1)


@pytest.mark.parametrize("plant", ["rms as text", "weakest without phase", "p05 as text", "draws as text"])
def test_planted_mistakes_refused_by_schema_and_model(schema, pose_block, plant):
    if plant in ("rms as text", "weakest without phase"):
        name, model, block = "pose_accuracy", PoseAccuracy, copy.deepcopy(pose_block)
        if plant == "rms as text":
            block["after"]["rms"]["error_translation_mm"] = "0.1 mm"
        else:
            del block["before"]["weakest"][0]["phase"]
    else:
        name, model, block = "robustness", Robustness, json.loads(json.dumps(robustness_block("robust")))
        if plant == "p05 as text":
            block["designs"]["recommended"]["camera"]["combined"]["p05"] = "low"
        else:
            block["objective"]["draws"] = "64"
    assert list(_validator(schema, name).iter_errors(block))
    with pytest.raises(pydantic.ValidationError):
        section({name: block}, name, model)
