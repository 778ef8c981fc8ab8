"""Hoist in-function imports to module top where that adds no import cycle and no heavy module (issue 19).

Static: builds the module-level import graph of cadfeat, and for every import statement directly in a function
body (with --nested also in its if/for/while/with blocks; never in try blocks) accepts it if (1) the target
cannot reach the importer (no cycle), (2) it adds no third-party package but numpy to the importer's import
closure (and no name that a package loads lazily through ``__getattr__``), (3) for modules on the
``cadfeat --help`` path it adds no module --help does not import today, and (4) its names clash with nothing.
Then check with ``python -X importtime -m cadfeat --help`` and ``ruff check --fix --select I``.

Usage (from the repository root): python tools/hoist_imports.py . HELP_MODULES_FILE [--nested] [-v]
[--apply | --annotate]; HELP_MODULES_FILE lists (whitespace-separated) the modules in sys.modules after
``cadfeat --help``; --annotate adds a ``# lazy: <why>`` comment to the first import left in each function.
"""

from __future__ import annotations

import ast
import importlib.util
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(sys.argv[1])
HELP = set(Path(sys.argv[2]).read_text().split())
APPLY = "--apply" in sys.argv
STDLIB = set(sys.stdlib_module_names)

files: dict[str, Path] = {}
for p in sorted((ROOT / "cadfeat").rglob("*.py")):
    rel = p.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__main__":
        continue
    if parts[-1] == "__init__":
        parts = parts[:-1]
    files[".".join(parts)] = p
MODS = set(files)


def is_pkg(m: str) -> bool:
    return files[m].name == "__init__.py"


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def parents(m: str) -> list[str]:
    ps = m.split(".")
    return [".".join(ps[:i]) for i in range(1, len(ps))]


def resolve(mod: str, node: ast.ImportFrom | ast.Import) -> list[str]:
    """Absolute module names a statement imports (for ImportFrom: the module plus submodule names)."""
    out: list[str] = []
    if isinstance(node, ast.Import):
        for a in node.names:
            out.append(a.name)
        return out
    base = node.module or ""
    if node.level:
        pkg = mod if is_pkg(mod) else mod.rpartition(".")[0]
        for _ in range(node.level - 1):
            pkg = pkg.rpartition(".")[0]
        base = f"{pkg}.{base}" if base else pkg
    out.append(base)
    for a in node.names:
        if f"{base}.{a.name}" in MODS:
            out.append(f"{base}.{a.name}")
    return out


def is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def top_imports(body: list[ast.stmt]) -> list[ast.Import | ast.ImportFrom]:
    out: list[ast.Import | ast.ImportFrom] = []
    for n in body:
        if isinstance(n, ast.Import | ast.ImportFrom):
            out.append(n)
        elif isinstance(n, ast.If):
            if not is_type_checking(n.test):
                out += top_imports(n.body) + top_imports(n.orelse)
        elif isinstance(n, ast.Try):
            out += top_imports(n.body) + top_imports(n.orelse) + top_imports(n.finalbody)
            for h in n.handlers:
                out += top_imports(h.body)
        elif isinstance(n, ast.With):
            out += top_imports(n.body)
        elif isinstance(n, ast.ClassDef):
            out += top_imports(n.body)
    return out


trees = {m: ast.parse(p.read_text()) for m, p in files.items()}
SRC = {m: p.read_text().splitlines() for m, p in files.items()}
edges: dict[str, set[str]] = defaultdict(set)  # module -> cadfeat modules or "ext:name"


def targets(m: str, node) -> set[str]:
    t: set[str] = set()
    for r in resolve(m, node):
        top = r.split(".")[0]
        if top == "cadfeat":
            for x in parents(r) + [r]:
                if x in MODS and x not in parents(m) and x != m:
                    t.add(x)
        elif top == "__future__":
            pass
        else:
            name = ".".join(r.split(".")[:2]) if top == "scipy" else top
            t.add(("std:" if top in STDLIB else "ext:") + name)
    return t


for m, tree in trees.items():
    for node in top_imports(tree.body):
        edges[m] |= targets(m, node)


def closure(start: str) -> set[str]:
    seen: set[str] = set()
    stack = [start]
    while stack:
        x = stack.pop()
        if x in seen:
            continue
        seen.add(x)
        if x in MODS:
            stack.extend(edges[x])
            stack.extend(p for p in parents(x))
    return seen


def bound_names(node) -> dict[str, str]:
    """name -> what it is bound to."""
    out = {}
    for a in node.names:
        if isinstance(node, ast.Import):
            if a.asname:
                out[a.asname] = f"import {a.name}"
            else:
                out[a.name.split(".")[0]] = f"import {a.name.split('.')[0]}"
        else:
            out[a.asname or a.name] = f"from {'.' * node.level}{node.module or ''} import {a.name}"
    return out


def local_bindings(fn) -> list[tuple[str, ast.AST]]:
    """(name, node) of every binding in fn's own scope (not nested defs)."""
    out = []
    a = fn.args
    for arg in a.posonlyargs + a.args + a.kwonlyargs + [a.vararg, a.kwarg]:
        if arg is not None:
            out.append((arg.arg, arg))

    def walk(n):
        for c in ast.iter_child_nodes(n):
            if isinstance(c, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                out.append((c.name, c))
                continue
            if isinstance(c, ast.Lambda):
                continue
            if isinstance(c, ast.Name) and isinstance(c.ctx, ast.Store | ast.Del):
                out.append((c.id, c))
            elif isinstance(c, ast.Import | ast.ImportFrom):
                for k in bound_names(c):
                    out.append((k, c))
            elif isinstance(c, ast.ExceptHandler) and c.name:
                out.append((c.name, c))
            elif isinstance(c, ast.Global | ast.Nonlocal):
                for k in c.names:
                    out.append((k, c))
            walk(c)
    for s in fn.body:
        if isinstance(s, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            out.append((s.name, s))
            continue
        walk(ast.Module(body=[s], type_ignores=[]))
        if isinstance(s, ast.Import | ast.ImportFrom):
            for k in bound_names(s):
                out.append((k, s))
    return out


def module_bindings(tree) -> dict[str, list[str]]:
    out: dict[str, list[str]] = defaultdict(list)

    def add_stmt(s):
        if isinstance(s, ast.Import | ast.ImportFrom):
            for k, v in bound_names(s).items():
                out[k].append(v)
        elif isinstance(s, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            out[s.name].append("def")
        else:
            for c in ast.walk(s):
                if isinstance(c, ast.Name) and isinstance(c.ctx, ast.Store):
                    out[c.id].append("assign")
                if isinstance(c, ast.ExceptHandler) and c.name:
                    out[c.name].append("assign")
            for attr in ("body", "orelse", "finalbody", "handlers"):
                for cc in getattr(s, attr, []) or []:
                    if isinstance(cc, ast.stmt | ast.ExceptHandler):
                        for c2 in ([cc] if isinstance(cc, ast.stmt) else cc.body):
                            if isinstance(c2, ast.Import | ast.ImportFrom | ast.FunctionDef | ast.ClassDef):
                                add_stmt(c2)
    for s in tree.body:
        add_stmt(s)
    return out


def functions(tree):
    """(fn, chain of enclosing fns) for every function."""
    res = []

    def rec(node, chain):
        for c in ast.iter_child_nodes(node):
            if isinstance(c, ast.FunctionDef | ast.AsyncFunctionDef):
                res.append((c, chain))
                rec(c, chain + [c])
            elif isinstance(c, ast.ClassDef):
                rec(c, chain)
            elif isinstance(c, ast.stmt):
                rec(c, chain)
    rec(tree, [])
    return res


HEAVY_NAMES = {"cadquery", "OCP", "pyvista", "vtk", "vtkmodules", "cv2", "trimesh", "matplotlib", "scipy.optimize",
               "scipy.stats", "scipy", "pymoo", "dask", "distributed", "numba", "PIL", "jinja2", "playwright",
               "fastapi", "uvicorn", "starlette", "build123d", "open3d", "sklearn", "pandas", "plotly"}

LIGHT = {"numpy"}
MODB = {mm: module_bindings(tt) for mm, tt in trees.items()}


def lazy_attribute(m: str, s) -> str | None:
    """A name imported from a cadfeat module that does not bind it (a lazy module ``__getattr__``)."""
    if not isinstance(s, ast.ImportFrom):
        return None
    base = resolve(m, s)[0]
    if base not in MODS:
        return None
    for a in s.names:
        if f"{base}.{a.name}" not in MODS and a.name not in MODB[base]:
            return f"{base}.{a.name}"
    return None


def body_imports(body, nested=("--nested" in sys.argv)):
    """(import, its block) directly in a function body, or (with --nested) in its if/for/while/with blocks."""
    out = []
    for st in body:
        if isinstance(st, ast.Import | ast.ImportFrom):
            out.append((st, body))
        elif nested and isinstance(st, ast.If | ast.For | ast.While | ast.With):
            for blk in (st.body, getattr(st, "orelse", [])):
                out += body_imports(blk, nested)
    return out


accepted: dict[str, list] = defaultdict(list)   # module -> [(fn, node)]
rejected: dict[str, list] = defaultdict(list)   # module -> [(fn, node, reason)]
hoisted_names: dict[str, dict[str, str]] = defaultdict(dict)
stats = defaultdict(int)

for m, tree in trees.items():
    modb = module_bindings(tree)
    for fn, chain in functions(tree):
        binds_cache = None
        for s, block in body_imports(fn.body):
            if any(a.name == "*" for a in s.names):
                continue
            tg = targets(m, s)
            own = any(t in MODS for t in tg) or (isinstance(s, ast.ImportFrom) and s.level > 0)
            stats["own" if own else "other"] += 1
            reason = None
            lines = SRC[m]
            if "# lazy:" in lines[s.lineno - 1] or "# lazy:" in lines[s.lineno - 2]:
                reason = "marked lazy"
            elif len(block) == 1:
                reason = "only statement"
            elif (lz := lazy_attribute(m, s)):
                reason = f"heavy: {lz} is loaded lazily by its package"
            # cycle
            if reason is None:
                for t in tg:
                    if t in MODS and m in closure(t):
                        reason = f"cycle: {t} imports {m}"
                        break
            cm = closure(m)
            if reason is None:
                add: set[str] = set()
                for t in tg:
                    add |= closure(t) if t in MODS else {t}
                new = add - cm
                ext = sorted(x[4:] for x in new if x.startswith("ext:"))
                if m not in HELP:
                    ext = [x for x in ext if x not in LIGHT]
                if ext:
                    heavy = [x for x in ext if x in HEAVY_NAMES] or ext
                    reason = f"heavy: would import {', '.join(heavy[:3])} at module load"
                elif m in HELP or any(x in HELP for x in [m]):
                    extra = sorted(x for x in new if x in MODS and x not in HELP)
                    extra_std = sorted(x[4:] for x in new if x.startswith("std:") and x[4:] not in HELP)
                    if isinstance(s, ast.ImportFrom) and not s.level and s.module:  # a stdlib submodule
                        extra_std += [f"{s.module}.{a.name}" for a in s.names if f"{s.module}.{a.name}" not in HELP
                                      and _is_module(f"{s.module}.{a.name}")]
                    if extra or extra_std:
                        reason = "keeps `cadfeat --help` fast (on the CLI start-up path)"
            if reason is None:
                if binds_cache is None:
                    binds_cache = local_bindings(fn)
                    for c in chain:
                        binds_cache += local_bindings(c)
                for k, v in bound_names(s).items():
                    others = [n for (name, n) in binds_cache if name == k and n is not s]
                    if any(not (isinstance(n, ast.Import | ast.ImportFrom) and bound_names(n).get(k) == v)
                           for n in others):
                        reason = f"name clash: {k}"
                        break
                    mv = modb.get(k, []) + ([hoisted_names[m][k]] if k in hoisted_names[m] else [])
                    if any(x != v for x in mv):
                        reason = f"name clash at module level: {k}"
                        break
            if reason is None:
                accepted[m].append((fn, s))
                for k, v in bound_names(s).items():
                    hoisted_names[m][k] = v
                for t in tg:
                    edges[m].add(t)
            else:
                rejected[m].append((fn, s, reason, own))

n_acc = sum(len(v) for v in accepted.values())
n_acc_own = sum(1 for v in accepted.values() for (_, s) in v
                if isinstance(s, ast.ImportFrom) and (s.level or (s.module or "").startswith("cadfeat"))
                or isinstance(s, ast.Import) and any(a.name.startswith("cadfeat") for a in s.names))
print(f"in-function import statements (direct in body): own={stats['own']} other={stats['other']}")
print(f"accepted {n_acc} (own {n_acc_own}), rejected {sum(len(v) for v in rejected.values())}")
reasons = defaultdict(int)
for v in rejected.values():
    for (_, _, r, own) in v:
        reasons[r.split(":")[0] + (" own" if own else " other")] += 1
print(dict(reasons))
if "-v" in sys.argv:
    for m, v in rejected.items():
        for fn, s, r, _own in v:
            print(f"  {m}:{s.lineno} {fn.name}: {ast.unparse(s)[:70]} -> {r}")

if APPLY:
    for m, lst in accepted.items():
        lazy = {(id(fn)): r for (fn, s, r, own) in rejected.get(m, []) if own}
        p = files[m]
        src = p.read_text().splitlines(keepends=True)
        tree = trees[m]
        delete = set()
        new_lines: list[str] = []
        seen = set()
        existing = {ast.unparse(n) for n in tree.body if isinstance(n, ast.Import | ast.ImportFrom)}
        for _fn, s in sorted(lst, key=lambda x: x[1].lineno):
            for ln in range(s.lineno, s.end_lineno + 1):
                delete.add(ln)
            txt = ast.unparse(s)
            if txt not in existing and txt not in seen:
                seen.add(txt)
                new_lines.append(txt + "\n")
        # insertion point: after last top-level import before first def/class
        ins = 0
        for n in tree.body:
            if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                break
            if isinstance(n, ast.Import | ast.ImportFrom):
                ins = n.end_lineno
            elif ins == 0 and isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant):
                ins = n.end_lineno
        # drop the blank line that followed a removed block when it would now follow a blank/def/docstring
        for i in sorted(delete):
            if i + 1 in delete or i + 1 > len(src) or src[i].strip():
                continue
            j = i - 1
            while j in delete:
                j -= 1
            prev = src[j - 1].rstrip() if j >= 1 else ""
            if not prev.strip() or prev.endswith(":") or prev.endswith('"' * 3) or prev.endswith("'" * 3):
                delete.add(i + 1)
        out = []
        for i, line in enumerate(src, start=1):
            if i in delete:
                continue
            out.append(line)
            if i == ins:
                out.extend(new_lines)
        if ins == 0:
            out = new_lines + out
        p.write_text("".join(out))

if "--annotate" in sys.argv:
    by_file: dict[str, list] = defaultdict(list)
    done_fn = set()
    for m, v in rejected.items():
        for fn, s, r, own in sorted(v, key=lambda x: x[1].lineno):
            if not own or id(fn) in done_fn:
                continue
            done_fn.add(id(fn))
            if r.startswith("cycle"):
                t = r.split(": ", 1)[1].split(" imports ")[0]
                c = f"lazy: import cycle ({t} imports {m})"
            elif "loaded lazily" in r:
                c = "lazy: its package loads it on first use"
            elif "--help" in r or m.startswith("cadfeat.cli"):
                c = "lazy: keeps `cadfeat --help` fast"
            elif r.startswith("heavy"):
                what = r.split("would import ", 1)[1].replace(" at module load", "")
                what = what.replace("pydantic_core, ", "").replace(", pydantic_core", "")
                what = what.replace("pydantic_core", "pydantic")
                c = f"lazy: would import {what} at module load"
            else:
                continue
            by_file[m].append((s.lineno, s.end_lineno, c))
    for m, items in by_file.items():
        p = files[m]
        src = p.read_text().splitlines(keepends=True)
        for lineno, end, c in sorted(items, reverse=True):
            line = src[lineno - 1]
            if "#" in line:
                continue
            body = line.rstrip("\n")
            if lineno == end and len(body) + 4 + len(c) <= 120:
                src[lineno - 1] = f"{body}  # {c}\n"
            else:
                indent = line[: len(line) - len(line.lstrip())]
                src.insert(lineno - 1, f"{indent}# {c}\n")
        p.write_text("".join(src))
    print("annotated", sum(len(v) for v in by_file.values()))
