"""Independent reference for CQGI part scripts: the script built by CadQuery's own CQGI, no cadfeat code."""
import re
from pathlib import Path


def cqgi_solid(path: Path, params: dict):
    """The script built by CQGI directly (no cadfeat code): its one solid. A parameter CQGI's finder misses (a
    negative or annotated constant) is written into the script's text, on its own line, as a user would edit it;
    a script written for cq-editor gets what cq-editor gives it (its ``__name__``, ``log``)."""
    import cadquery as cq
    from cadquery import cqgi

    src = path.read_text().replace("describe_parameter(", "(lambda *a: None)(")  # (upstream bug: test_cqgi_parts)
    if "__cq_main__" in src:  # a script guarded for cq-editor (if __name__ == "__cq_main__": ...) run as cq-editor
        src = f'__name__ = "__cq_main__"\n{src}'
    if re.search(r"\blog\(", src):  # cq-editor's log(x)
        src = f"log = print\n{src}"
    known = cqgi.parse(src).metadata.parameters
    for name, value in params.items():
        if name not in known:
            src, n = re.subn(rf"^({name}\s*(?::\s*\w+)?\s*=\s*)[^#\n]+", rf"\g<1>{value!r} ", src, flags=re.M)
            assert n == 1, f"{name} is not one line of {path}"
    result = cqgi.parse(src).build(build_parameters={k: v for k, v in params.items() if k in known})
    assert result.success, result.exception
    shown = result.results[0].shape
    if not isinstance(shown, cq.Workplane | cq.Shape):  # a build123d-like object: its OCP shape is .wrapped
        return cq.Shape.cast(shown.wrapped)
    return shown.val() if isinstance(shown, cq.Workplane) else shown
