"""The documentation in docs/: generated pages equal a fresh generation, README stays a newcomer's page, links
between README and docs resolve, and the annotated example study meets the JSON Schema.

The docs build itself (``make docs``: mkdocs --strict, broken links, anchors and API references fail) runs in
``make test`` after lint; these checks are the ones that need no MkDocs.
"""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _tool(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("tool", ["gen_study_reference", "gen_cli_reference"])
def test_generated_page_is_current(tool):
    """A settings model or a command changed without regenerating its page: run ``python tools/<tool>.py``."""
    module = _tool(tool)
    assert module.PAGE.read_text(encoding="utf-8") == module.generate(), (
        f"{module.PAGE.relative_to(ROOT)} is out of date: run python tools/{tool}.py")


def test_study_reference_lists_every_key():
    """Every section and key of the schema appears in the reference, with its default."""
    from cadfeat.study.json_schema import study_json_schema

    text = (DOCS / "guide" / "study-reference.md").read_text(encoding="utf-8")
    schema = study_json_schema()
    for section, sec in schema["properties"].items():
        assert f"## [{section}]" in text
        forms = sec.get("oneOf", [sec])
        for form in forms:
            for key in form.get("properties", {}):
                assert f"| `{key}` |" in text, f"[{section}] {key} missing from the study reference"
    assert "| `edge_distance_mm` | number | `1.0` |" in text


def test_readme_is_a_newcomers_page():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= 150, f"README has {len(lines)} lines; details belong in docs/"
    top = "\n".join(lines[:12])
    assert "make demo" in top and "make test" in top, "the two commands must stay at the top of README"
    assert max(len(p.split()) for p in re.split(r"\n\s*\n", text)) <= 150, "a README paragraph over 150 words"


def _links(path: Path) -> list[str]:
    text = path.read_text(encoding="utf-8")
    return [m for m in re.findall(r"\]\(([^)\s]+)\)", text) if "://" not in m and not m.startswith("#")]


def test_readme_links_resolve():
    for link in _links(ROOT / "README.md"):
        target = (ROOT / link.split("#")[0]).resolve()
        assert target.exists(), f"README links to {link}, which does not exist"


def test_every_page_is_in_the_navigation():
    """mkdocs --strict refuses a page outside the nav too; this says which, without MkDocs."""
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in DOCS.rglob("*.md"):
        rel = page.relative_to(DOCS).as_posix()
        assert rel in nav, f"docs/{rel} is not in mkdocs.yml's nav"


def test_annotated_example_meets_the_schema():
    """The annotated study of docs/guide/study-files.md meets the JSON Schema (``jsonschema``, an independent
    validator; tests/study/test_study_schema.py loads it with ``load_study``)."""
    jsonschema = pytest.importorskip("jsonschema")
    from cadfeat.study.json_schema import study_json_schema

    text = (DOCS / "guide" / "study-files.md").read_text(encoding="utf-8")
    block = re.search(r"```toml\n(.*?)```", text[text.index("## An annotated study"):], re.S).group(1)
    jsonschema.validate(tomllib.loads(block), study_json_schema())


def test_package_cites_the_docs_not_a_missing_design_file():
    """The repository is self-contained: the code cites docs/design.md, not a DESIGN.md it does not have."""
    offenders = [str(p.relative_to(ROOT)) for base in ("cadfeat", "tests", "benchmarks", "studies", "tools")
                 for p in (ROOT / base).rglob("*") if p.suffix in (".py", ".toml") and p != Path(__file__)
                 and re.search(r"(?<!docs/)\bDESIGN\.md", p.read_text(encoding="utf-8", errors="replace"))]
    assert not offenders, f"cite docs/design.md instead of DESIGN.md in {offenders}"
