"""The package's import graph has no circles (issue 40), and its packages import only downwards (issue 61).

A circle (module A imports B and B imports A, directly or through others) makes the import
order matter and hides which module is the lower one. The graph is read from the source with
``ast``: every ``import`` and ``from ... import`` statement, those inside functions and under
``if TYPE_CHECKING`` included (a deferred import is still an edge, only a hidden one).
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "metasheet"

#: the circles issue 40 untied, as (lower, upper) after the fix: each must stay one way
UNTIED = [
    ("metasheet.robot.statics", "metasheet.robot.equilibrium"),  # force_scale, residual_floor moved down
    ("metasheet.robot.qp", "metasheet.robot.inverse"),  # qp reads a StepSettings protocol
    ("metasheet.rom.coordinates", "metasheet.rom.model"),  # ReducedState, ReducedBasis moved down
    ("metasheet.rom.linearizer", "metasheet.rom.model"),
    ("metasheet.rom.model", "metasheet.rom.training"),  # projected_state moved to coordinates
    ("metasheet.sheet.grid", "metasheet.sheet.icesl"),  # GridBox moved down, angles reads it there
    ("metasheet.sheet.angles", "metasheet.sheet.icesl"),
    ("metasheet.sheet.outline", "metasheet.sheet.geometry"),  # SheetParams, ARM_ANGLES moved down
    ("metasheet.sheet.mesh_control", "metasheet.sheet.geometry"),
    ("metasheet.runtime.priority_pool", "metasheet.runtime.executor"),  # kill_workers moved down
]


def modules(root: Path = ROOT) -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package's ``__init__``) for every module under ``root``."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        out[".".join(parts[:-1] if is_pkg else parts)] = (path, is_pkg)
    return out


def _absolute(module: str | None, level: int, here: str, is_pkg: bool) -> str:
    """The absolute name of ``from <level dots><module> import`` written in module ``here``."""
    if level == 0:
        return module or ""
    base = here.split(".") if is_pkg else here.split(".")[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (``from pkg import sub`` counts as ``pkg.sub``)."""
    mods = modules(root)
    graph = {}
    for name, (path, is_pkg) in mods.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = _absolute(node.module, node.level, name, is_pkg)
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    targets.add(sub if sub in mods else base)
        graph[name] = {t for t in targets if t in mods and t != name}
    return graph


def two_cycles(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Pairs of modules that import each other, sorted."""
    return sorted({tuple(sorted((a, b))) for a, deps in graph.items() for b in deps if a in graph.get(b, ())})


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm,
    iterative: no recursion limit on a deep graph): each holds at least one circle."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return sorted(out)


def test_the_graph_reader_sees_every_kind_of_import(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from . import b\nfrom .sub.c import X\n")
    (pkg / "b.py").write_text("def f():\n    from .a import g\n")
    (pkg / "d.py").write_text("import numpy\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..d import Y\nimport pkg.b\n")
    g = import_graph(pkg)
    assert g["pkg.a"] == {"pkg.b", "pkg.sub.c"}
    assert g["pkg.b"] == {"pkg.a"}  # inside a function
    assert g["pkg.sub.c"] == {"pkg.d", "pkg.b"}  # under TYPE_CHECKING, and absolute
    assert g["pkg.d"] == set()  # outside the package: no edge
    assert two_cycles(g) == [("pkg.a", "pkg.b")]
    assert circles(g) == [["pkg.a", "pkg.b", "pkg.sub.c"]]


@pytest.fixture(scope="module")
def package_graph() -> dict[str, set[str]]:
    """metasheet's own import graph, read once for the tests below (parsing every module)."""
    return import_graph()


@pytest.mark.parametrize("lower, upper", UNTIED)
def test_an_untied_circle_stays_one_way(lower, upper, package_graph):
    g = package_graph
    assert lower in g and upper in g, "a module of issue 40's layout is missing"
    assert upper not in g[lower], f"{lower} imports {upper} again: the edge must point {upper} -> {lower}"


def test_no_two_modules_import_each_other(package_graph):
    assert two_cycles(package_graph) == []


def test_no_circle_at_all(package_graph):
    assert circles(package_graph) == []


#: The allowed order between metasheet's packages and root modules, lowest first: a module may
#: import from its own layer and the layers below it, never from above (issue 61). A new
#: package or root module must be placed here.
LAYERS = (
    ("errors", "conventions", "version", "runtime"),                  # the basics, how metasheet runs
    ("mechanics", "published"),                                       # materials, the published numbers
    ("fem", "cells"),                                                 # elements and solvers, cells
    ("homogenize", "sheet"),                                          # homogenisation, the sheet
    ("robot", "viz"),                                                 # the robot FEM, the pictures
    ("rom", "design", "dynamics"),                                    # the reduced robot, the sheet's design, time
    ("studies", "report"),                                            # the paper's studies, the report
    ("pipeline", "supervise"),                                        # stages, files, the watched run
    ("api", "serve", "goto", "export",                                # what users call
     "cli_output", "cli_files", "cli_export", "cli_path", "cli_robot_options"),
    ("cli", "__main__", "(root)"),                                    # the command, the top level
)


def package_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "(root)"


def upward_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """The edges ``(a, b)`` of ``graph`` whose target lies in a higher layer than its source;
    ValueError naming the packages :data:`LAYERS` does not place."""
    layer = {name: i for i, names in enumerate(LAYERS) for name in names}
    unplaced = sorted({package_of(m) for m in graph} - set(layer))
    if unplaced:
        raise ValueError(f"place these in LAYERS: {unplaced}")
    return sorted((a, b) for a, bs in graph.items() for b in bs if layer[package_of(b)] > layer[package_of(a)])


def test_every_import_goes_down_the_layers(package_graph):
    up = upward_imports(package_graph)
    assert up == [], "imports that go up the layers:\n" + "\n".join(f"{a} -> {b}" for a, b in up)


def test_the_layer_check_sees_an_upward_import_and_an_unplaced_package():
    graph = {"metasheet.robot.statics": {"metasheet.pipeline.runner", "metasheet.fem.tet4"},
             "metasheet.pipeline.runner": {"metasheet.robot.statics"}, "metasheet.fem.tet4": set()}
    assert upward_imports(graph) == [("metasheet.robot.statics", "metasheet.pipeline.runner")]
    with pytest.raises(ValueError, match=r"place these in LAYERS: \['newpkg'\]"):
        upward_imports({**graph, "metasheet.newpkg.x": set()})
