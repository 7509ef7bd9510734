"""Dependencies point one way: nothing below ``bedstruct.diagnose`` imports it, and the
modules of ``diagnose`` import one another without a circle (function-body imports count)."""

from __future__ import annotations

import ast
import pathlib

import bedstruct.diagnose as dg

ROOT = pathlib.Path(dg.__file__).resolve().parents[1]      # the bedstruct package
#: Packages below the diagnosis: they never import it.
BELOW = ("analysis", "core", "dem", "io", "workflows")


def _imports(path: pathlib.Path, module: str, is_pkg: bool) -> set[str]:
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parent = base[:len(base) - (node.level - 1)]
                target = ".".join(parent + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def _graph() -> dict[str, set[str]]:
    mods = {}
    for p in ROOT.rglob("*.py"):
        parts = list(p.relative_to(ROOT.parent).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        name = ".".join(parts[:-1] if is_pkg else parts)
        mods[name] = (p, is_pkg)
    return {m: {t for t in _imports(p, m, pkg) if t in mods and t != m}
            for m, (p, pkg) in mods.items()}


def test_nothing_below_the_diagnosis_imports_it():
    graph = _graph()
    bad = [(m, t) for m, ts in graph.items() for t in ts
           if (m.split(".") + [""])[1] in BELOW and t.startswith("bedstruct.diagnose")]
    assert bad == []


def test_the_diagnosis_modules_import_one_another_without_a_circle():
    graph = {m: {t for t in ts if t.startswith("bedstruct.diagnose.")}
             for m, ts in _graph().items() if m.startswith("bedstruct.diagnose.")}
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(m):
        state[m] = 1
        path.append(m)
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                raise AssertionError("import circle: " + " -> ".join(path[path.index(t):] + [t]))
            if t not in state:
                visit(t)
        path.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)


def test_the_public_names_are_a_static_list():
    tree = ast.parse((ROOT / "diagnose" / "__init__.py").read_text(encoding="utf-8"))
    assigned = [n for n in tree.body if isinstance(n, ast.Assign)
                and any(getattr(t, "id", None) == "__all__" for t in n.targets)]
    assert len(assigned) == 1 and isinstance(assigned[0].value, ast.List)
    assert all(isinstance(e, ast.Constant) for e in assigned[0].value.elts)
    assert len(set(dg.__all__)) == len(dg.__all__)
    assert all(hasattr(dg, name) for name in dg.__all__)


def test_the_method_never_imports_its_validation():
    """``bedstruct.diagnose.validation`` uses the method; no module of the method (nor anything
    else outside the validation, the package's face and the CLI) imports it."""
    graph = _graph()
    allowed = ("bedstruct.diagnose.validation", "bedstruct.cli")
    bad = [(m, t) for m, ts in graph.items() for t in ts
           if t.startswith("bedstruct.diagnose.validation")
           and not m.startswith(allowed) and m != "bedstruct.diagnose"]
    assert bad == []
    assert any(t.startswith("bedstruct.diagnose.validation") for t in graph["bedstruct.diagnose"])
