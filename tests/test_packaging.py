"""What a non-editable install ships: every package directory of ours, and the ranges data.

Asked of setuptools itself (its expansion of pyproject.toml: include, exclude, namespaces),
and the package data by the glob setuptools applies (relative to the package directory)."""

import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _setuptools_config() -> dict:
    from setuptools.config.pyprojecttoml import read_configuration

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "[tool.setuptools] support is still beta"
        return read_configuration(str(ROOT / "pyproject.toml"), expand=True)["tool"]["setuptools"]


def test_every_package_directory_is_installed():
    shipped = set(_setuptools_config()["packages"])
    ours = {".".join(p.parent.relative_to(ROOT).parts) for top in ("plant_sim", "monitor", "hydromon")
            for p in (ROOT / top).rglob("__init__.py")}
    assert {"hydromon.commands", "hydromon.bench", "monitor.audit"} <= ours
    assert ours <= shipped, ours - shipped
    assert not any(p.startswith("tests") for p in shipped)


def test_the_ranges_data_is_installed():
    globs = _setuptools_config()["package-data"]["monitor"]
    shipped = {p for g in globs for p in (ROOT / "monitor").glob(g)}
    data = set((ROOT / "monitor" / "data").glob("*.json"))
    assert {p.name for p in data} >= {"table3.json", "default_ranges.json"}
    assert data <= shipped, data - shipped


def test_the_core_never_imports_the_shell():
    # DESIGN.md 2: monitor/ and plant_sim/ are the functional core; hydromon/ (zenoh, MCAP,
    # files, CLI, the bus contract) is built on them, never the other way round
    import ast

    offenders = []
    for top in ("plant_sim", "monitor"):
        for path in (ROOT / top).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                         else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
                offenders += [f"{path.relative_to(ROOT)}: {n}" for n in names
                              if n.split(".")[0] in ("hydromon", "zenoh", "mcap")]
    assert not offenders, offenders


def test_the_parameter_names_are_the_plants_identified_ones():
    from monitor.names import PARAM_NAMES
    from plant_sim.params import PlantParams

    assert tuple(PlantParams().identified()) == PARAM_NAMES
