"""results.json as the typed ``StudyResults`` model and its JSON Schema (``cadfeat schema --results``).

Independent reference: the ``jsonschema`` library (Draft 2020-12) validates the file cadfeat wrote against the
written schema, and refuses planted mistakes that the model refuses too; the round trip
``StudyResults.read(f).to_data()`` equals the file's JSON as ``json`` reads it (``tools/compare_results.py``).
"""

from __future__ import annotations

import copy
import json

import jsonschema
import pytest
from study_helpers import SMALL, STEP, compare_results_tool, no_report

from cadfeat.cli import main
from cadfeat.results import SCHEMA_VERSION, StudyResults
from cadfeat.study import evaluate_study


@pytest.fixture(scope="module")
def results_validator(tmp_path_factory):
    out = tmp_path_factory.mktemp("schema") / "results.schema.json"
    assert main(["schema", "--results", "--out", str(out)]) == 0
    schema = json.loads(out.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    assert str(SCHEMA_VERSION) in schema["$id"] and schema["properties"]["schema_version"]["const"] == SCHEMA_VERSION
    return jsonschema.Draft202012Validator(schema)


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    """An evaluate-only results.json of a STEP study (as test_compare_results builds it)."""
    mp = pytest.MonkeyPatch()
    no_report(mp)
    data = copy.deepcopy(SMALL)
    data["study"] = {"name": "step_plate", "part": str(STEP), "seed": 2}
    data["design"] = {"holes": [{"select": [-25.0, -15.0, 10.0], "max_offset_mm": 6.0}]}
    data["trajectory"]["target"] = [0.0, 0.0, 10.0]
    out = tmp_path_factory.mktemp("eval")
    evaluate_study(data, out)
    mp.undo()
    return out / "results.json"


def test_written_results_meet_the_schema_and_round_trip(results_validator, evaluated):
    data = json.loads(evaluated.read_text())
    assert not [e.message for e in results_validator.iter_errors(data)]
    typed = StudyResults.read(evaluated.parent)
    assert compare_results_tool().compare(data, typed.to_data(), ignore=()) == []
    assert typed.study.name == "step_plate" and typed.objectives.names == data["objectives"]["names"]
    assert not typed.is_run and typed.holes.before[0].name == data["holes"]["before"][0]["name"]


@pytest.mark.parametrize("plant", ["no study", "n_samples text", "hole radius text", "verdict without decision"])
def test_planted_mistakes_are_refused_by_schema_and_model(results_validator, evaluated, plant):
    data = json.loads(evaluated.read_text())
    if plant == "no study":
        del data["study"]
    elif plant == "n_samples text":
        data["trajectory"]["n_samples"] = "12"
    elif plant == "hole radius text":
        data["holes"]["before"][0]["radius_mm"] = "3"
    else:
        data["verdict"] = {"limiting": None, "findings": []}
    assert not results_validator.is_valid(data)
    with pytest.raises(ValueError):
        StudyResults.from_data(data)


def test_a_new_section_passes_through_unchanged(evaluated):
    """A section (or a key inside one) added by newer code is kept and written back (extra="allow")."""
    data = json.loads(evaluated.read_text())
    data["closed_loop_check"] = {"ekf": {"rms_mm": 0.5}}
    data["objectives"]["new_key"] = [1, 2.5]
    assert StudyResults.from_data(data).to_data() == data
