"""``hydromon record``: the recorder node (bus -> MCAP files)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.stop import stop_on_signals

NAME = "record"
HELP = "record everything under <namespace>/** into MCAP files (json + jsonschema channels)"
EXAMPLES = (
    'hydromon record --out tour.mcap --mode client --connect tcp/127.0.0.1:7447',
)


def add_arguments(parser) -> None:
    parser.add_argument("--out", default=".", metavar="PATH",
                        help="a .mcap file, or a directory for time-stamped files (default: .)")
    parser.add_argument("--rotate-mb", type=float, default=None, metavar="MB",
                        help="start a new file once the current one reaches this many MB (1e6 B)")
    parser.add_argument("--rotate-s", type=float, default=None, metavar="S",
                        help="start a new file once the current one is this many seconds old")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")
    parser.add_argument("--max-payload-mb", type=float, default=None, metavar="MB",
                        help="payloads larger than this are counted and not recorded (default 1 MB = 1e6 B; "
                             "a contract payload is under 2 kB)")
    add_bus_arguments(parser)


def run(args) -> int:
    from hydromon.cli.checks import non_negative, positive, writable_dir
    from hydromon.bus.recorder import MAX_PAYLOAD_BYTES, names_a_directory, record

    # before the bus is opened: a bad option is one error line, not a session that is torn down
    positive("--rotate-mb", args.rotate_mb, unit="MB")
    positive("--rotate-s", args.rotate_s)
    positive("--max-payload-mb", args.max_payload_mb, unit="MB")
    non_negative("--duration", args.duration, unit="s")
    # --out as the recorder reads it: a directory for its files, or a file whose directory is created
    writable_dir("--out", args.out if names_a_directory(args.out) else Path(args.out).parent)
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        with session_from_args(args) as session:
            try:
                result = record(
                    session, args.out, namespace=args.namespace,
                    rotate_bytes=None if args.rotate_mb is None else max(1, round(args.rotate_mb * 1e6)),
                    rotate_seconds=args.rotate_s, duration_s=args.duration, stop_event=stop,
                    max_payload_bytes=MAX_PAYLOAD_BYTES if args.max_payload_mb is None
                    else max(1, round(args.max_payload_mb * 1e6)),
                    on_file=lambda p: print(f"hydromon record: writing {p}", file=sys.stderr, flush=True))
            except OSError as exc:  # creating or writing the files (the checks above cannot see /proc, a full disk)
                raise OSError(exc.errno, f"--out {args.out!r}: {exc.strerror or exc}", exc.filename) from None
    finally:
        restore_signals()
    print(f"hydromon record: {result.messages} messages in {len(result.files)} file(s)"
          + (f"; {result.not_json} non-JSON payloads not recorded" if result.not_json else "")
          + (f"; {result.too_large} payloads over --max-payload-mb not recorded" if result.too_large else "")
          + (f"; {result.failed} messages that could not be recorded" if result.failed else "")
          + (f"; the disk was full {result.disk_full} time(s): {result.unwritten} messages received then not "
             "recorded" if result.disk_full else ""),
          file=sys.stderr)
    for path in result.files:
        print(path)
    return 0
