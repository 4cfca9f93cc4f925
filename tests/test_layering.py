"""The shape of the code: what an install ships, which package may import which, no import
cycle, no module too long to read.

Layers, lowest first; a package imports only packages of its own layer or below:

    hydromon.contract   the shared vocabulary (keys, payloads, rig constants, names, units)
    plant_sim           the rig's physics
    monitor             identification, grading, calibration, audit (pure)
    hydromon.engine     the monitor without the bus
    hydromon.store      MCAP, CSV, replay from files
    hydromon.report     tables, JSON documents, plots
    hydromon.bus        zenoh nodes
    hydromon.dashboard  the web dashboard and the Foxglove bridge
    hydromon.tools      bench, goldens, doc generation
    hydromon.cli        the command line
"""

import ast
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TOPS = ("plant_sim", "monitor", "hydromon")
LAYERS = ("hydromon.contract", "plant_sim", "monitor", "hydromon.engine", "hydromon.store", "hydromon.report",
          "hydromon.bus", "hydromon.dashboard", "hydromon.tools", "hydromon.cli")
# third-party packages that only some layers may use: the numerical core and the vocabulary
# stay free of I/O, the bus is zenoh's, files are the store's, pictures the report's
ONLY_IN = {
    # store: key expressions only
    "zenoh": {"hydromon.bus", "hydromon.cli", "hydromon.tools", "hydromon.store", "hydromon.dashboard"},
    "mcap": {"hydromon.store", "hydromon.tools"},
    "matplotlib": {"hydromon.report", "hydromon.tools"},
    "rich": {"hydromon.report", "hydromon.cli"},
    # the web server and the Foxglove bridge are the dashboard's
    "starlette": {"hydromon.dashboard"},
    "uvicorn": {"hydromon.dashboard"},
    "foxglove": {"hydromon.dashboard"},
}
MAX_LINES = 450


def _modules() -> dict[str, Path]:
    out = {}
    for top in TOPS:
        for path in (ROOT / top).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _imports(path: Path, module: str) -> list[str]:
    """Every module ``module`` (at ``path``) imports, anywhere in it but under ``if TYPE_CHECKING``."""
    tree = ast.parse(path.read_text())
    skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
            for n in ast.walk(node)}
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1] + ([base] if base else []))
            out += [f"{base}.{a.name}" for a in node.names] + [base]
    return out


def _layer(module: str) -> int | None:
    for i, layer in enumerate(LAYERS):
        if module == layer or module.startswith(layer + "."):
            return i
    return None


MODULES = _modules()


def test_every_package_imports_only_its_own_layer_or_below():
    offenders = []
    for module, path in MODULES.items():
        mine = _layer(module)
        for name in _imports(path, module):
            theirs = _layer(name)
            if mine is not None and theirs is not None and theirs > mine:
                offenders.append(f"{module} imports {name} ({LAYERS[theirs]} is above {LAYERS[mine]})")
            top = name.split(".")[0]
            if top in ONLY_IN and (mine is None or LAYERS[mine] not in ONLY_IN[top]):
                offenders.append(f"{module} imports {top}")
    assert not offenders, "\n".join(offenders)


def test_every_module_of_ours_belongs_to_a_layer():
    assert [m for m in MODULES if m != "hydromon" and _layer(m) is None] == []


def test_no_import_cycle_among_the_modules():
    graph = {m: {n for n in _imports(p, m) if n in MODULES and n != m} for m, p in MODULES.items()}
    # a package's __init__ that re-exports its modules is not a cycle with them
    graph = {m: {n for n in deps if not (MODULES[n].name == "__init__.py" and m.startswith(n + "."))}
             for m, deps in graph.items()}
    state, cycles = {}, []

    def visit(m, stack):
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                cycles.append(" -> ".join(stack[stack.index(n):] + [n]))
            elif n not in state:
                visit(n, stack + [n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, "\n".join(cycles)


@pytest.mark.parametrize("top", [*TOPS, "tests"])
def test_no_module_is_too_long_to_read(top):
    long = {str(p.relative_to(ROOT)): n for p in (ROOT / top).rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, long


def _setuptools_config() -> dict:
    from setuptools.config.pyprojecttoml import read_configuration

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "[tool.setuptools] support is still beta"
        return read_configuration(str(ROOT / "pyproject.toml"), expand=True)["tool"]["setuptools"]


def test_every_package_directory_is_installed():
    # asked of setuptools itself (its expansion of pyproject.toml: include, exclude, namespaces)
    shipped = set(_setuptools_config()["packages"])
    ours = {".".join(p.parent.relative_to(ROOT).parts) for top in TOPS for p in (ROOT / top).rglob("__init__.py")}
    assert {"hydromon.cli.commands", "hydromon.tools.bench", "monitor.audit"} <= ours
    assert ours <= shipped, ours - shipped
    assert not any(p.startswith("tests") for p in shipped)


def test_the_ranges_data_is_installed():
    globs = _setuptools_config()["package-data"]["monitor"]
    shipped = {p for g in globs for p in (ROOT / "monitor").glob(g)}
    data = set((ROOT / "monitor" / "data").glob("*.json"))
    assert {p.name for p in data} >= {"table3.json", "default_ranges.json"}
    assert data <= shipped, data - shipped


def test_the_dashboards_pages_and_vendored_library_are_installed():
    # every file the web server serves comes from the package (no CDN): each must be package data
    globs = _setuptools_config()["package-data"]["hydromon.dashboard"]
    root = ROOT / "hydromon" / "dashboard"
    shipped = {p for g in globs for p in root.glob(g)}
    served = {p for p in (root / "static").rglob("*") if p.is_file()}
    names = {p.relative_to(root / "static").as_posix() for p in served}
    assert {"fleet.html", "rig.html", "events.html", "vendor/uplot/uPlot.iife.min.js", "vendor/uplot/LICENSE",
            "vendor/uplot/VERSION", "foxglove/hydromon-layout.json"} <= names
    assert served <= shipped, served - shipped


def test_the_parameter_names_are_the_plants_identified_ones():
    from hydromon.contract import PARAM_NAMES, PARAM_UNITS
    from plant_sim.params import PlantParams

    assert tuple(PlantParams().identified()) == PARAM_NAMES == tuple(PARAM_UNITS)
