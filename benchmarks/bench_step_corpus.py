"""Benchmark: real STEP parts — ``load_step`` against plain STEP import, and re-drill time per hole.

Over a corpus of STEP parts (a folder given as the first argument or ``CADFEAT_STEP_CORPUS``; default the
committed corner-case fixtures tests/data/corner_cases, since third-party parts may not be committed): for
each part, the median time of a plain STEP import (``cadfeat.cad.export.import_step``: the baseline,
measured in the same run) and of ``load_step`` (import + model tolerances + hole extraction), their ratio,
and the time to re-drill each of up to ``MAX_HOLES`` holes moved by 1 % of its radius (``dry_run``: fill,
cut, volume / B-rep / re-extraction checks), or the reason it is refused.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import median_s as _median_s
from benchutil import save_section

MAX_HOLES = 4
MAX_FACES = 600  # larger parts: import and load_step timed, not re-drilled (keeps the run under ~2 min)


def main(corpus: Path | None = None, quick: bool = False) -> str:
    from cadfeat.cad.export import import_step
    from cadfeat.cad.step_parts import dry_run, load_step
    from cadfeat.errors import CadfeatError

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    corpus = corpus or Path(os.environ.get("CADFEAT_STEP_CORPUS", ROOT / "tests" / "data" / "corner_cases"))
    paths = sorted(p for p in corpus.iterdir() if p.suffix.lower() in (".step", ".stp"))
    repeats = 1 if quick else 3
    import_step(paths[0])  # the first STEP read of a process initialises OCCT's reader: not timed
    rows, per_hole, refused, ratios = [], [], 0, []
    for path in paths:
        t_import = _median_s(lambda p=path: import_step(p), repeats)
        t_load = _median_s(lambda p=path: load_step(p), repeats)
        part = load_step(path)
        times, notes = [], []
        if len(part.shape.Faces()) <= MAX_FACES:
            for hole in part.holes[:MAX_HOLES]:
                t0 = time.perf_counter()
                try:
                    dry_run(part, [hole])
                    times.append(time.perf_counter() - t0)
                except CadfeatError as exc:
                    refused += 1
                    why = str(exc).split("): ", 1)[-1].split(" mm: ", 1)[-1]
                    notes.append(f"{hole.name}: {why[:70]}…")
        per_hole += times
        ratios.append(t_load / t_import)
        redrill = f"{statistics.median(times) * 1e3:.0f}" if times else "–"
        rows.append(f"| {path.name} | {len(part.shape.Faces())} | {len(part.holes)} | {t_import * 1e3:.1f} | "
                    f"{t_load * 1e3:.1f} | {t_load / t_import:.2f} | {len(times)} | {redrill} | "
                    f"{'; '.join(notes) or ''} |")
    default = corpus == ROOT / "tests" / "data" / "corner_cases"
    where = ("the committed corner-case fixtures (tests/data/corner_cases)" if default else
             "a local corpus of real third-party parts (not committed; sources and licences listed in docs/results.md)")
    lines = [
        f"## STEP parts{'' if default else ' (real, third-party)'}: load_step vs plain import, re-drill per hole "
        f"({'bench_step_corpus' if default else 'bench_step_corpus, real corpus'})",
        "",
        f"Machine: {machine}. Corpus: {where}, {len(paths)} parts. Median of {repeats} runs per part. Baseline:",
        "plain STEP import (`import_step`) of the same file in the same run; ratio = load_step / import. Re-drill:",
        f"`dry_run` of up to {MAX_HOLES} holes per part (fill, cut 1 % of the radius away, volume/B-rep/",
        f"re-extraction checks), parts with ≤ {MAX_FACES} faces.",
        "",
        "| part | faces | holes | import (ms) | load_step (ms) | ratio | re-drilled | re-drill/hole (ms) | refused |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|",
        *rows,
        "",
        f"load_step / import: median ratio {statistics.median(ratios):.2f} (min {min(ratios):.2f}, max "
        f"{max(ratios):.2f}). Re-drill per hole: median {statistics.median(per_hole) * 1e3:.0f} ms, max "
        f"{max(per_hole) * 1e3:.0f} ms over {len(per_hole)} holes; {refused} refused with a reason."
        if per_hole else "No hole re-drilled.",
    ]
    name = "bench_step_corpus" if default else "bench_step_corpus_real"
    return save_section(name, "\n".join(lines))


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    print(main(Path(args[0]) if args else None, quick="--quick" in sys.argv))
