"""``hydromon recover``: salvage a cut recording (e.g. its recorder was killed)."""

from __future__ import annotations

import json
import os
import sys

NAME = "recover"
HELP = ("rewrite a truncated or damaged MCAP recording into a valid one with every surviving message "
        "(exit 1 when damaged chunks before its end or messages without a channel had to be left out; "
        "a file cut short, its last chunk unfinished, exits 0 and says where it was cut)")
EXAMPLES = (
    'hydromon recover cut-off.mcap -o whole.mcap',
)


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="the damaged .mcap recording (left untouched)")
    parser.add_argument("-o", "--out", default=None, metavar="OUT",
                        help="where to write (default: FILE with .recovered.mcap)")
    parser.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON document")


def default_output(path: str) -> str:
    """``x.mcap`` -> ``x.recovered.mcap``."""
    stem = path[:-len(".mcap")] if path.endswith(".mcap") else path
    return stem + ".recovered.mcap"


def run(args) -> int:
    from dataclasses import asdict

    from hydromon.cli.checks import replace_on_success, writable_file
    from hydromon.store.mcap_recover import recover

    if os.path.isdir(args.file):
        raise ValueError(f"{args.file}: is a directory; give the damaged .mcap file")
    if not os.path.isfile(args.file):
        raise FileNotFoundError(f"{args.file}: no such file")
    out = args.out or default_output(args.file)
    writable_file("--out", out)  # a directory or a missing one: a clear error, not a traceback
    if os.path.exists(out) and not args.force:
        raise ValueError(f"{out} exists; pass --force to overwrite it")
    if os.path.exists(out) and os.path.samefile(args.file, out):
        raise ValueError(f"recover: destination {out} is the source")
    # written whole beside OUT and renamed into it: a failed run leaves an existing OUT as it was
    with replace_on_success(out, "wb") as f:
        report = recover(args.file, f)
        if report.messages == 0:  # before the rename: no empty "recovered" file, and exit 2
            raise ValueError(f"{args.file}: nothing to recover ({report.summary()}); {out} not written")
    if args.json:
        print(json.dumps({"out": out, **asdict(report)}))
    else:
        print(f"{out}: {report.summary()}")
    print(f"hydromon recover: wrote {out}", file=sys.stderr)
    # a file cut short is what recover is for (exit 0); data it had to leave out of the middle
    # is a loss a script must not walk past: written, but exit 1
    if report.chunks_lost or report.orphans:
        print(f"hydromon recover: {out} is missing data the source held (see the report)", file=sys.stderr)
        return 1
    return 0
