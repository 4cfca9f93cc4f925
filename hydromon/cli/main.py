"""``hydromon``: one entry point; each subcommand is a module in hydromon/cli/commands.

A command module defines ``NAME``, ``HELP``, ``EXAMPLES`` (command lines shown at the end of its
``--help``), ``add_arguments(parser)`` and ``run(args) -> int``, ``DESCRIPTION`` if its ``--help``
says more than ``HELP``, and ``KERNELS`` if it runs the compiled numerical kernels (see
:func:`_compile_notice`). Exit statuses: ``hydromon.cli.exits``.
Argument parsing lives here and in those modules only; the work they call is elsewhere.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import logging
import os
import pkgutil
import re
import sys
import threading

from hydromon.cli import commands
from hydromon.tools import jitcache

DESCRIPTION = ("physics-based health grading of hydraulic position servos (Lin et al. 2023): simulated "
               "or real rigs on Zenoh, graded live, recorded to MCAP; `hydromon COMMAND --help` for each")


def _command_modules():
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda i: i.name):
        if not info.name.startswith("_"):
            yield importlib.import_module(f"hydromon.cli.commands.{info.name}")


def version() -> str:
    """hydromon's version, as installed."""
    from importlib.metadata import PackageNotFoundError, version as installed

    try:
        return installed("hydromon")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


class Parser(argparse.ArgumentParser):
    """argparse with a command's examples at the end of its ``--help`` and "did you mean" for a
    mistyped option or command (Python 3.11's argparse has no ``suggest_on_error``)."""

    def __init__(self, *args, examples: tuple[str, ...] = (), **kw):
        super().__init__(*args, **kw)
        self.examples = tuple(examples)

    def format_help(self) -> str:
        text = super().format_help()
        if self.examples:
            text += "\nexamples:\n" + "".join(f"  {e}\n" for e in self.examples)
        return text

    def _options(self) -> list[str]:
        return [o for a in self._actions for o in a.option_strings if o.startswith("--")]

    def error(self, message: str):
        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            near = difflib.get_close_matches(m.group(1), re.findall(r"'([^']*)'", m.group(2)), n=1)
            if near:
                message += f"; did you mean {near[0]}?"
        super().error(message)

    def parse_args(self, args=None, namespace=None):
        if self._commands():  # hydromon's own options come before the command: a typo there too
            for word in sys.argv[1:] if args is None else args:
                if not word.startswith("-"):
                    break
                opt = word.split("=", 1)[0]
                if opt.startswith("--") and opt not in self._options():
                    near = difflib.get_close_matches(opt, self._options(), n=1, cutoff=0.7)
                    self.error(f"unrecognized arguments: {word}" + (f"; did you mean {near[0]}?" if near else ""))
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            # the command's own parser names the command and knows its options
            command = getattr(ns, "command", None)
            target = self._commands().get(command, self)
            hints = []
            for word in extras:
                opt = word.split("=", 1)[0]
                if opt.startswith("--"):
                    near = difflib.get_close_matches(opt, target._options(), n=1, cutoff=0.7)
                    if near:
                        hints.append(f"{opt}: did you mean {near[0]}?")
            target.error(f"unrecognized arguments: {' '.join(extras)}" + (f"; {'; '.join(hints)}" if hints else ""))
        return ns

    def _commands(self) -> dict:
        for a in self._actions:
            if isinstance(a, argparse._SubParsersAction):
                return a.choices
        return {}


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="hydromon", description=DESCRIPTION,
                    examples=("hydromon demo", "hydromon evaluate FILE.mcap", "hydromon COMMAND --help"))
    parser.add_argument("--version", action="version", version=f"hydromon {version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP),
                           examples=getattr(mod, "EXAMPLES", ()))
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run, _kernels=getattr(mod, "KERNELS", False))
    return parser


COMPILE_NOTICE_AFTER_S = 2.0
"""A command that uses the numerical kernels and is still running this long after it started
on a cold cache says why it is slow."""


def _compile_notice(args) -> threading.Timer | None:
    """Started for a command whose module sets ``KERNELS`` (True, the source directories whose
    kernels it runs, or a function of its arguments giving either) when numba's cache holds
    none of them: its first kernel calls compile for about a minute, with nothing else to show
    for it."""
    kernels = getattr(args, "_kernels", False)
    kernels = kernels(args) if callable(kernels) else kernels
    if not kernels or not jitcache.is_cold(dirs=None if kernels is True else tuple(kernels)):
        return None
    timer = threading.Timer(COMPILE_NOTICE_AFTER_S, lambda: print(
        f"hydromon {args.command}: first run of this version on this machine: compiling the numerical "
        "kernels (about a minute; cached for every later run)", file=sys.stderr, flush=True))
    timer.daemon = True
    timer.start()
    return timer


def main(argv: list[str] | None = None) -> int:
    jitcache.configure()  # before any command module imports a kernel
    args = build_parser().parse_args(argv)
    notice = _compile_notice(args)
    try:
        if getattr(args, "zenoh_config", None) is not None:  # a bad file: one line, before anything starts
            from hydromon.bus.session import load_config_file

            load_config_file(args.zenoh_config)
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
    except ConnectionError as exc:  # the bus (hydromon.bus.session.open_session): not a usage error, not a crash
        print(f"hydromon {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # the system refused (a full disk, a permission): one line, not a traceback
        print(f"hydromon {args.command}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if notice is not None:
            notice.cancel()


def entry() -> None:
    """The ``hydromon`` console script (and ``python -m hydromon.cli``): :func:`main`, then out
    without the interpreter's finalization.

    Zenoh's runtime threads outlive a closed session; one that touches Python while the
    interpreter finalizes is stopped mid-unwind and aborts the process (SIGABRT, "FATAL:
    exception not rethrown": one ``hydromon demo`` in 14 under load, after its work was done and
    reported). Every command has closed its files and sessions when it returns, so the output
    is flushed and the process leaves with the command's status.
    """
    try:
        code = main()
    except SystemExit as exc:  # argparse: --help (0) or a usage error (2), already printed
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        if not isinstance(exc.code, (int, type(None))):
            print(exc.code, file=sys.stderr)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BrokenPipeError:  # the reader left before the last bytes: as main() does
            code = code or 141
        except (OSError, ValueError):
            pass
    logging.shutdown()
    os._exit(code)


