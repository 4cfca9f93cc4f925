"""Generate docs/cli.md, the command-line reference, from the argparse parser.

``python -m hydromon.cli.reference`` rewrites the file; ``--check`` exits 1 if it is stale.
A test runs the check, so the reference cannot drift from ``hydromon.cli.main.build_parser()``:
every command's help, usage and options come from the parser itself.

The text does not depend on the terminal: argparse wraps usage lines to the terminal width
(``COLUMNS``), so every parser here gets a formatter of a fixed width (:data:`WIDTH`).
"""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path

from hydromon.cli.main import DESCRIPTION, build_parser

__all__ = ["render", "DOC_PATH", "WIDTH", "main"]

DOC_PATH = Path(__file__).resolve().parents[2] / "docs" / "cli.md"
WIDTH = 100
"""Columns of the usage blocks (argparse's own wrapping, at a fixed width)."""

_FORMATTER = functools.partial(argparse.HelpFormatter, width=WIDTH, max_help_position=30)

_INTRO = """\
Every command prints the same text with `--help`. A command that fails on its input prints one
line, `hydromon COMMAND: error: ...`, on stderr. Exit status:

| status | meaning |
| --- | --- |
| 0 | done; for the commands that give a verdict (`evaluate`, `audit`, `watch --once`): every rig graded, and the grade can be trusted (status `ok`). `replay --direct` exits 0 once it replayed: its output is the verdicts, each with its status |
| 1 | graded but not to be trusted, or not graded: a rig's status is `bad-input`, `uncalibrated` (no ranges made for its constants), `stale`, `converging` or `commissioning`; `audit`: the record does not obey the model, or a rig of a recording could not be audited (its row says why); `watch --once`: no monitor answered. Also: the work ran but did not succeed: the bus could not be opened, the system refused (disk full, permission), `recover` left messages out, a bus `replay` was cut short |
| 2 | a usage error: a bad option (with the closest one when it is a misspelling), or a file that cannot be read as what it should be; nothing was started |
| 130 | stopped by Ctrl-C before the command finished its own way |
| 141 | the reader of stdout went away (`hydromon evaluate FILE --json \\| head -c 100`) |

With `--json` a command prints one JSON document on stdout and nothing else; logs and progress
go to stderr. The node commands (`sim`, `monitor`, `record`, `replay`, `watch`) share the
`bus (zenoh)` options; see [operations.md](operations.md) for how to combine them.
"""


def _text(text: str) -> str:
    """argparse's help as Markdown: one line; outside code spans, ``<``, ``>`` and ``*`` escaped
    (``<namespace>/rig/*/sample`` must not read as an HTML tag or emphasis)."""
    parts = " ".join(text.split()).split("`")
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("<", "&lt;").replace(">", "&gt;").replace("*", "\\*")
    return "`".join(parts)


def _cell(text: str) -> str:
    """Text for a Markdown table cell: :func:`_text`, pipes escaped."""
    return _text(text).replace("|", "\\|")


def _code_cell(text: str) -> str:
    """Text as code in a Markdown table cell (GitHub reads an escaped pipe there as a pipe)."""
    return "`" + text.replace("|", "\\|") + "`"


def _fixed_width(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = _FORMATTER


def _subparsers(parser: argparse.ArgumentParser) -> tuple[argparse._SubParsersAction, dict]:
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return action, action.choices


def _option(formatter: argparse.HelpFormatter, action: argparse.Action) -> str:
    """``--name METAVAR`` (every spelling), or a positional's metavar."""
    if not action.option_strings:
        return formatter._format_args(action, action.dest)
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    args = formatter._format_args(action, action.dest.upper())
    return ", ".join(f"{s} {args}" for s in action.option_strings)


def _options(parser: argparse.ArgumentParser) -> list[str]:
    """One table per argument group: option and what it does (argparse's own help text)."""
    formatter = parser._get_formatter()
    out = []
    for group in parser._action_groups:
        actions = [a for a in group._group_actions if a.help is not argparse.SUPPRESS]
        if not actions:
            continue
        out += [f"{group.title}:", "", "| option | what |", "| --- | --- |"]
        for action in actions:
            what = formatter._expand_help(action) if action.help else ""
            out.append(f"| {_code_cell(_option(formatter, action))} | {_cell(what)} |")
        out.append("")
    return out


def render() -> str:
    """The text of docs/cli.md."""
    parser = build_parser()
    _fixed_width(parser)
    sub_action, commands = _subparsers(parser)
    helps = {a.dest: a.help for a in sub_action._choices_actions}
    out = [
        "# hydromon command line",
        "",
        "<!-- generated by `python -m hydromon.cli.reference` from hydromon.cli.main.build_parser(); do not edit -->",
        "",
        f"`hydromon COMMAND [options]`: {DESCRIPTION}.",
        "",
        "| command | what it does |",
        "| --- | --- |",
        *(f"| [`{name}`](#hydromon-{name}) | {_cell(helps[name])} |" for name in sorted(commands)),
        "",
        _INTRO,
    ]
    for name in sorted(commands):
        p = commands[name]
        _fixed_width(p)
        out += [
            f"## hydromon {name}",
            "",
            _text(p.description or helps[name]),
            "",
            "```text",
            p.format_usage().strip(),
            "```",
            "",
            *_options(p),
            *(["examples:", "", "```bash", *p.examples, "```", ""] if getattr(p, "examples", ()) else []),
        ]
    return "\n".join(out).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hydromon.cli.reference", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if docs/cli.md is stale")
    parser.add_argument("--out", type=Path, default=DOC_PATH)
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        current = args.out.read_text() if args.out.exists() else None
        if current != text:
            print(f"{args.out} is stale; run `python -m hydromon.cli.reference`", file=sys.stderr)
            return 1
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
