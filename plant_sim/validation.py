"""One-line pydantic validation errors, for the config models' messages (rig constants, fleet
files, health ranges) and the CLI: pydantic's own text spans several lines per problem, with
the whole input and a web address."""

from __future__ import annotations

from pydantic import ValidationError

__all__ = ["brief_error"]

_GOT_MAX = 60  # characters of a rejected input shown (a whole table is not echoed back)


def brief_error(exc: ValidationError) -> str:
    """A pydantic error in one line: ``where: what (got value)`` per problem, ``; ``-separated."""
    parts = []
    for e in exc.errors():
        where = ".".join(str(x) for x in e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        got = ""
        if e["type"] != "value_error":
            shown = repr(e.get("input"))
            got = f" (got {shown if len(shown) <= _GOT_MAX else shown[:_GOT_MAX - 3] + '...'})"
        parts.append(f"{where + ': ' if where else ''}{msg}{got}")
    return "; ".join(parts)
