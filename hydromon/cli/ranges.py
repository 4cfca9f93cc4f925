"""The ``--ranges`` option that monitor, evaluate and replay share (one text, one parse)."""

from __future__ import annotations

RANGES_HELP = ('health ranges: "default" (the reference rig\'s: Table 3 with the valve on its static gain K_sv), '
               '"paper" (Table 3 as printed: grades K_sv omega^2) or a ranges file (hydromon commission makes one for '
               'your rig; ./paper for a file of that name). Ranges grade only rigs with the constants they were made '
               'for; any other rig is reported ungraded (uncalibrated)')


def add_ranges_argument(parser, help: str = RANGES_HELP) -> None:
    parser.add_argument("--ranges", default=None, metavar="paper|default|FILE", help=help)


def ranges_from_args(args):
    """``monitor.ranges.Ranges`` of ``--ranges`` (None when not given: the default); a file
    that cannot be read or is not valid ranges is a ValueError naming it."""
    if args.ranges is None:
        return None
    from monitor.ranges import Ranges

    return Ranges.resolve(args.ranges)
