"""The Foxglove layout hydromon ships (``static/foxglove/hydromon-layout.json``, the app's layout
import format: ``configById`` and a ``layout`` tree of panel ids), made here from the rig ids.

Two tabs: *Fleet* (an Indicator per rig on its grade, a State Transitions panel of every rig's
grade and status over time, and a Table of ``<ns>/fleet``) and *Rig* (one rig: a Plot per graded
parameter with its ``-+ 3 SE`` band and band edges, its grade and status as State Transitions, and
a Table of its events). Every topic it names is one the bridge advertises (the bus keys); on a
recording the same topics exist, but for ``<ns>/fleet`` and the ``bands`` fields, which only the
live bridge adds.

``python -m hydromon.dashboard.foxglove_layout`` writes the shipped file (the paper's five Table 4
rigs, ``table4-g1`` .. ``table4-g5``, as ``hydromon demo`` and ``hydromon sim`` run them).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from hydromon.contract import DEFAULT_NAMESPACE, GRADES, PARAM_UNITS, UNKNOWN
from hydromon.report.zones import GRADE_COLOURS

__all__ = ["layout", "layout_topics", "SHIPPED", "DEFAULT_RIGS", "GRADED"]

SHIPPED = Path(__file__).with_name("static") / "foxglove" / "hydromon-layout.json"
DEFAULT_RIGS = tuple(f"table4-g{i}" for i in range(1, 6))
GRADED = ("K_sv", "f_c", "B_fv", "C_ip", "C_ep")
"""The parameters the default ranges grade (``monitor/data/default_ranges.json``)."""
COLOURS = GRADE_COLOURS
EDGE_NAMES = ("health|sub-health", "sub-health|average", "average|deterioration", "deterioration|fault")


def _indicator(ns: str, rig: str) -> dict:
    return {"path": f"{ns}/rig/{rig}/health.grade", "style": "background", "fallbackColor": COLOURS[UNKNOWN],
            "fallbackLabel": f"{rig}: no verdict",
            "rules": [{"operator": "=", "rawValue": g, "color": COLOURS[g], "label": f"{rig}: {g}"}
                      for g in (*GRADES, UNKNOWN)]}


def _plot(ns: str, rig: str, p: str) -> dict:
    base = f"{ns}/rig/{rig}/health"
    unit = PARAM_UNITS[p]
    series = [{"value": f"{base}.params.{p}", "enabled": True, "timestampMethod": "receiveTime",
               "label": f"{p} [{unit}]", "color": "#1d2228"},
              {"value": f"{base}.bands.{p}.lo", "enabled": True, "timestampMethod": "receiveTime",
               "label": "-3 SE", "color": "#8a9199"},
              {"value": f"{base}.bands.{p}.hi", "enabled": True, "timestampMethod": "receiveTime",
               "label": "+3 SE", "color": "#8a9199"}]
    series += [{"value": f"{base}.bands.{p}.edges[{i}]", "enabled": True, "timestampMethod": "receiveTime",
                "label": name, "color": COLOURS[GRADES[i + 1]]} for i, name in enumerate(EDGE_NAMES)]
    return {"title": f"{rig}: {p} [{unit}]", "paths": series, "showLegend": True, "legendDisplay": "floating",
            "showXAxisLabels": True, "showYAxisLabels": True, "xAxisVal": "timestamp", "isSynced": True}


def _split(direction: str, items: list, pct: float | None = None):
    """A mosaic tree of ``items`` (panel ids or subtrees) side by side."""
    if len(items) == 1:
        return items[0]
    return {"direction": direction, "first": items[0], "second": _split(direction, items[1:]),
            "splitPercentage": pct if pct is not None else 100 / len(items)}


def layout(namespace: str = DEFAULT_NAMESPACE, rigs=DEFAULT_RIGS, rig: str = "table4-g3") -> dict:
    """The layout for ``rigs`` (fleet tab) and ``rig`` (rig tab)."""
    cfg: dict[str, dict] = {}
    indicators = []
    for r in rigs:
        pid = f"Indicator!{r}"
        cfg[pid] = _indicator(namespace, r)
        indicators.append(pid)
    cfg["StateTransitions!fleet"] = {"paths": [{"value": f"{namespace}/rig/{r}/health.grade", "timestampMethod":
                                                "receiveTime", "label": r} for r in rigs], "isSynced": True}
    cfg["Table!fleet"] = {"topicPath": f"{namespace}/fleet.rigs"}
    fleet_tab = _split("column", [_split("row", indicators), "StateTransitions!fleet", "Table!fleet"], 20)
    plots = []
    for p in GRADED:
        pid = f"Plot!{rig}-{p}"
        cfg[pid] = _plot(namespace, rig, p)
        plots.append(pid)
    cfg["StateTransitions!rig"] = {"paths": [
        {"value": f"{namespace}/rig/{rig}/health.grade", "timestampMethod": "receiveTime", "label": f"{rig} grade"},
        {"value": f"{namespace}/rig/{rig}/health.status", "timestampMethod": "receiveTime", "label": f"{rig} status"}],
        "isSynced": True}
    cfg["Table!events"] = {"topicPath": f"{namespace}/rig/{rig}/event"}
    cfg[f"Indicator!rig-{rig}"] = _indicator(namespace, rig)
    rig_tab = _split("column", [_split("row", [f"Indicator!rig-{rig}", "StateTransitions!rig"], 25),
                                _split("row", [_split("column", plots[:3]), _split("column", plots[3:])]),
                                "Table!events"], 18)
    cfg["Tab!main"] = {"activeTabIdx": 0, "tabs": [{"title": "Fleet", "layout": fleet_tab},
                                                   {"title": f"Rig {rig}", "layout": rig_tab}]}
    return {"configById": cfg, "globalVariables": {}, "userNodes": {}, "playbackConfig": {"speed": 1},
            "layout": "Tab!main"}


_PATH_TOPIC = re.compile(r"^([A-Za-z0-9_/-]+)")


def layout_topics(doc: dict) -> set[str]:
    """Every topic a layout's panels name (the part of each message path before its first field)."""
    out = set()
    for conf in doc["configById"].values():
        paths = [conf.get("path"), conf.get("topicPath")] + [p.get("value") for p in conf.get("paths", [])]
        for path in filter(None, paths):
            out.add(_PATH_TOPIC.match(path).group(1))
    return out


def main() -> None:
    SHIPPED.parent.mkdir(parents=True, exist_ok=True)
    SHIPPED.write_text(json.dumps(layout(), indent=1) + "\n")
    print(SHIPPED)


if __name__ == "__main__":
    main()
