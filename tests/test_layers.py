"""The package's layers: imports point down only, no cycles, no hidden
imports inside functions, no oversized modules.

The allowed order is written down once, here (README: Architecture). A
module may import modules of its own layer or of any layer below it.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "sm2ith_drake"

# Lowest first. Each entry: layer name, the modules (dotted, without the
# "sm2ith_drake." prefix) that belong to it; a package name covers its
# submodules.
LAYERS = [
    ("base", ["", "errors", "resources", "geometry"]),  # "" = the package
    ("robots", ["robots"]),
    (
        "scenario",
        [
            "scenario",
            "scenario_hardware",
            "scenario_options",
            "scenario_checks",
            "scenario_loader",
        ],
    ),
    ("humans", ["humans"]),  # world models and the messages
    ("control", ["control"]),  # the math of the controller
    ("planning", ["planning"]),  # task sequences
    ("systems", ["systems"]),  # thin LeafSystems
    ("lcm", ["lcm"]),  # LeafSystems that speak LCM, codecs, lcm types
    ("diagrams", ["diagrams"]),  # every builder
    ("run", ["run"]),  # runners, metrics, benchmark
    ("experiments", ["experiments"]),  # campaigns, statistics, plots
    ("cli", ["cli"]),  # the sm2ith command
]
# Imports allowed inside functions: optional dependencies only.
OPTIONAL = {"ray", "pydot"}
MAX_LINES = 450
GENERATED = "lcm.sm2ith_lcmtypes"  # lcm-gen output, not ours to cut


def _Modules():
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).with_suffix("")
        parts = [p for p in rel.parts if p != "__init__"]
        out[".".join(parts)] = path
    return out


def _Layer(module: str) -> int:
    best, level = -1, None
    for i, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if prefix == "" and module == "":
                return i
            if prefix and (module == prefix or module.startswith(prefix + ".")):
                if len(prefix) > best:
                    best, level = len(prefix), i
    if level is None:
        raise AssertionError(f"module sm2ith_drake.{module} is in no layer")
    return level


def _Imports(path: Path, modules: dict):
    """(imported module, line, inside a function) of every sm2ith_drake
    import, and the names of function-level imports of other packages."""
    tree = ast.parse(path.read_text())
    found, inner = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        else:
            continue
        nested = node.col_offset > 0
        for name in names:
            if not name.startswith("sm2ith_drake"):
                if nested:
                    inner.append((name.split(".")[0], node.lineno))
                continue
            target = name.removeprefix("sm2ith_drake").lstrip(".")
            while target and target not in modules:
                target = target.rpartition(".")[0]
            found.append((target, node.lineno, nested))
    return found, inner


def test_every_module_is_in_a_layer():
    for module in _Modules():
        _Layer(module)


def test_imports_point_down_only_and_never_hide_in_functions():
    modules = _Modules()
    problems = []
    for module, path in modules.items():
        here = _Layer(module)
        found, inner = _Imports(path, modules)
        for target, line, nested in found:
            if nested:
                problems.append(f"{path.name}:{line} imports {target} in a function")
            if _Layer(target) > here:
                problems.append(
                    f"sm2ith_drake.{module} ({LAYERS[here][0]}) imports "
                    f"sm2ith_drake.{target} ({LAYERS[_Layer(target)][0]}), "
                    f"a higher layer (line {line})"
                )
        for name, line in inner:
            if name not in OPTIONAL:
                problems.append(f"{path.name}:{line} imports {name} in a function")
    assert not problems, "\n".join(problems)


def test_no_import_cycles():
    modules = _Modules()
    graph = {
        m: {t for t, _, _ in _Imports(p, modules)[0] if t != m}
        for m, p in modules.items()
    }
    # A package's __init__ may import its own submodules (re-exports); those
    # edges are not dependencies between layers.
    for m in graph:
        graph[m] = {t for t in graph[m] if not (m and t.startswith(m + "."))}
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == "open":
                cycles.append(stack[stack.index(t) :] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles: " + "; ".join(" → ".join(c) for c in cycles)


@pytest.mark.parametrize("module", sorted(_Modules()))
def test_modules_are_small(module):
    if module.startswith(GENERATED):
        pytest.skip("generated by lcm-gen")
    lines = len(_Modules()[module].read_text().splitlines())
    assert lines <= MAX_LINES, f"sm2ith_drake.{module} has {lines} lines"


def test_the_checks_can_fail(tmp_path):
    """The layer rule itself: a module of a low layer importing a higher one
    is found (a check of the test, on a synthetic module)."""
    fake = tmp_path / "fake.py"
    fake.write_text("from sm2ith_drake.cli.main import main\n")
    modules = dict(_Modules(), **{"geometry_fake": fake})
    found, _ = _Imports(fake, modules)
    assert found and _Layer(found[0][0]) > _Layer("geometry")
