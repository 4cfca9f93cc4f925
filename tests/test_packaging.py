"""What a non-editable install ships: every package directory of ours, and the ranges data."""

import tomllib
from pathlib import Path

from setuptools import find_packages

ROOT = Path(__file__).resolve().parent.parent


def test_every_package_directory_is_installed():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    shipped = set(find_packages(str(ROOT), include=cfg["packages"]["find"]["include"]))
    ours = {".".join(p.parent.relative_to(ROOT).parts) for top in ("plant_sim", "monitor", "hydromon")
            for p in (ROOT / top).rglob("__init__.py")}
    assert ours and ours <= shipped, ours - shipped
    assert not any(p.startswith("tests") for p in shipped)
    data = cfg["package-data"]["monitor"]
    assert all(any(f.relative_to(ROOT / "monitor").match(g) for g in data)
               for f in (ROOT / "monitor" / "data").glob("*.json"))
