"""``hydromon``: one entry point; each subcommand is a module in hydromon/commands.

A command module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.
Argument parsing lives here and in those modules only; the work they call is elsewhere.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import os
import sys

from hydromon import commands

DESCRIPTION = ("physics-based health grading of hydraulic position servos (Lin et al. 2023): simulated "
               "or real rigs on Zenoh, graded live, recorded to MCAP; `hydromon COMMAND --help` for each")


def _command_modules():
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda i: i.name):
        if not info.name.startswith("_"):
            yield importlib.import_module(f"hydromon.commands.{info.name}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hydromon", description=DESCRIPTION)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # stdout closed by the reader (`... --json | head`): not our error
        try:
            sys.stdout = open(os.devnull, "w")  # the interpreter's final flush must not fail again
        except OSError:
            pass
        return 141  # 128 + SIGPIPE, as a shell reports a pipe's writer
    except (ValueError, FileNotFoundError) as exc:
        print(f"hydromon {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
