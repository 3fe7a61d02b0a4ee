"""The core's layers (issue #38 §3, docs/architecture.md): every module of ``crates/cable-core``
imports only from the layers below it, and no two files of one module import each other.

Test code (everything from a file's first ``#[cfg(test)]`` on, and ``tests.rs`` files) may
import from anywhere: tests sit above the library."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "crates" / "cable-core" / "src"

#: bottom to top; a module may use the modules of lower layers only
LAYERS: list[set[str]] = [
    {"error"},
    {"lanes"},
    {"friction"},
    {"cable", "nn", "cdpr"},  # cable laws, network inference, the parallel robots' statics
    {"dynamics"},  # the models (the Model trait, every plant)
    {"integrate"},  # RK4 and step advice over any Model
    {"control"},  # controllers closing the loop around a model
    {"identify", "estimate"},  # the diagnosis' grey-box fits, the square-root UKF
    {"forceps"},  # the seed-000 applications over all of it
]
LAYER = {m: i for i, layer in enumerate(LAYERS) for m in layer}


def _library_code(path: Path) -> str:
    """A source file without its tests and comments."""
    if path.name == "tests.rs":
        return ""
    text = path.read_text(encoding="utf-8")
    cut = text.find("#[cfg(test)]")
    if cut >= 0:
        text = text[:cut]
    return re.sub(r"//.*", "", text)


def _top(path: Path) -> str:
    return path.relative_to(SRC).parts[0].removesuffix(".rs")


def _imports() -> list[tuple[str, str, str]]:
    """(file, its module, the module it names) for every ``crate::<module>`` path (not macros)."""
    out = []
    for f in sorted(SRC.rglob("*.rs")):
        if f.name == "lib.rs":
            continue
        for dep in sorted(set(re.findall(r"crate::(\w+)\b(?!!)", _library_code(f)))):
            if dep != _top(f):
                out.append((str(f.relative_to(SRC)), _top(f), dep))
    return out


def test_every_module_has_a_layer() -> None:
    tops = {_top(f) for f in SRC.rglob("*.rs")} - {"lib"}
    assert tops == set(LAYER), f"modules without a layer: {tops - set(LAYER)}; gone: {set(LAYER) - tops}"


def test_the_core_imports_only_downwards() -> None:
    upward = [(f, dep) for f, mod, dep in _imports() if dep in LAYER and LAYER[dep] >= LAYER[mod]]
    assert not upward, "imports that are not from a lower layer: " + ", ".join(
        f"{f} -> {d}" for f, d in upward
    )


def test_the_checker_sees_an_upward_import(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the check itself can fail: a statics file naming the dynamics layer is caught
    (tmp_path / "cdpr").mkdir()
    (tmp_path / "cdpr" / "plant.rs").write_text("use crate::dynamics::Model;\n// crate::control\n")
    (tmp_path / "dynamics.rs").write_text("use crate::cdpr::Robot;\n#[cfg(test)]\nuse crate::forceps;\n")
    monkeypatch.setattr(sys.modules[__name__], "SRC", tmp_path)
    found = _imports()
    assert ("cdpr/plant.rs", "cdpr", "dynamics") in found
    assert all(dep not in ("control", "forceps") for _, _, dep in found)


def _file_graph(directory: Path) -> dict[str, set[str]]:
    """Within one module directory: which sibling files each file names (``super::x``,
    ``crate::<module>::x``)."""
    files = {f.stem: f for f in directory.glob("*.rs")}
    graph: dict[str, set[str]] = {}
    for stem, f in files.items():
        code = _library_code(f)
        names = set(re.findall(r"super::(\w+)", code)) | set(
            re.findall(rf"crate::{directory.name}::(\w+)", code)
        )
        graph[stem] = {n for n in names if n in files and n != stem and n != "mod"}
    return graph


#: two-file loops allowed (none: the last two, inside identify, were broken by moving the
#: nominal plant's replays to identify/nominal.rs and the candidates' parameters beside them)
KNOWN_LOOPS: set[str] = set()


def test_no_two_files_of_a_module_import_each_other() -> None:
    loops = set()
    for d in sorted(p for p in SRC.iterdir() if p.is_dir()):
        g = _file_graph(d)
        loops |= {f"{d.name}/{a} <-> {b}" for a in g for b in g[a] if a < b and a in g.get(b, set())}
    assert loops <= KNOWN_LOOPS, "new two-file loops: " + ", ".join(sorted(loops - KNOWN_LOOPS))
    # and the statics of the parallel robots are out of the loop they were in with the plant
    assert not any(loop.startswith("cdpr/") for loop in loops)


BINDING = SRC.parents[1] / "cable-py" / "src"
#: the longest a binding function may be, signature to closing brace (issue #38 §3): a binding
#: checks, converts, releases the GIL, calls the core and converts back
MAX_BINDING_LINES = 40


def _functions(path: Path) -> list[tuple[str, int]]:
    """(name, lines from ``fn`` to its closing brace) of every function in a Rust file."""
    lines = path.read_text(encoding="utf-8").split("\n")
    out, i = [], 0
    while i < len(lines):
        m = re.match(r"^(\s*)(?:pub(?:\([a-z]+\))? )?fn (\w+)", lines[i])
        if m:
            indent, name = m.group(1), m.group(2)
            j = i
            while not lines[j].rstrip().endswith("{") and j < len(lines) - 1:
                j += 1
            k = j + 1
            while k < len(lines) and lines[k].rstrip() != indent + "}":
                k += 1
            out.append((name, k - i + 1))
            i = k
        i += 1
    return out


def test_no_binding_function_is_longer_than_forty_lines() -> None:
    long = [
        f"{f.name}:{name} ({n} lines)"
        for f in sorted(BINDING.glob("*.rs"))
        for name, n in _functions(f)
        if n > MAX_BINDING_LINES
    ]
    assert not long, "binding functions over 40 lines: " + ", ".join(long)


def test_the_length_check_counts_a_function(tmp_path: Path) -> None:
    body = "\n".join(f"    let x{i} = {i};" for i in range(45))
    f = tmp_path / "x.rs"
    f.write_text(f"fn short() {{\n}}\n\nimpl A {{\n    pub fn long(&self) {{\n{body}\n    }}\n}}\n")
    assert _functions(f) == [("short", 2), ("long", 47)]


STUB = SRC.parents[2] / "python" / "cablekit" / "_cablekit.pyi"


def _stub() -> ast.Module:
    return ast.parse(STUB.read_text(encoding="utf-8"))


def _docstring(node: ast.AST) -> bool:
    body = getattr(node, "body", [])
    first = body[0] if body else None
    return (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    )


def test_docstrings_live_in_the_binding_only() -> None:
    # one copy of every docstring: the Rust doc comments, which the extension carries at run
    # time; the stub holds the types (checked against the module by mypy.stubtest)
    tree = _stub()
    copies = [
        getattr(node, "name", "?")
        for node in ast.walk(tree)
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)) and _docstring(node)
    ]
    assert not copies, f"docstrings copied into the stub: {copies}"


def test_every_public_name_of_the_extension_is_documented() -> None:
    import inspect

    from cablekit import _cablekit as ext

    missing = []
    for node in _stub().body:
        if isinstance(node, ast.FunctionDef) and not (getattr(ext, node.name).__doc__ or "").strip():
            missing.append(node.name)
        if not isinstance(node, ast.ClassDef):
            continue
        cls = getattr(ext, node.name)
        text = cls.__doc__ or ""
        if not text.strip():
            missing.append(node.name)
        for name, attr in vars(cls).items():
            if name.startswith("_") or not (inspect.isroutine(attr) or inspect.isdatadescriptor(attr)):
                continue
            # a method documents itself; a property or a result's field may instead be named
            # (as a word) in its class's docstring, where the result classes describe their fields
            named = inspect.isdatadescriptor(attr) and re.search(rf"\b{re.escape(name)}\b", text)
            if not (attr.__doc__ or "").strip() and not named:
                missing.append(f"{node.name}.{name}")
    assert not missing, f"undocumented at run time: {missing}"
