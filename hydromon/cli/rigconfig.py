"""``--config FILE``: a rig's constants for a record that carries none (a CSV), or to override
the ones an MCAP recorded. The file is the JSON of ``hydromon.contract.RigConfig``, as a rig
publishes it on ``<ns>/rig/<id>/config`` (SI, or texts with their unit such as ``"12MPa"``;
missing fields take the paper's values)."""

from __future__ import annotations

from pathlib import Path

CONFIG_HELP = ("rig constants as JSON (the RigConfig published on <ns>/rig/<id>/config, SI, or a text with its "
               "unit, e.g. \"p_s\": \"12MPa\"; missing fields "
               "take the paper's values, sample_rate included): a CSV carries none, so without it the paper's "
               "rig at 100 Hz is assumed; for an MCAP it replaces the recorded constants")


def add_config_argument(parser) -> None:
    parser.add_argument("--config", metavar="FILE", help=CONFIG_HELP)


def config_from_args(args):
    """The RigConfig of ``--config`` (None without it); errors name the file."""
    if getattr(args, "config", None) is None:
        return None
    from pydantic import ValidationError

    from hydromon.contract import RigConfig

    path = Path(args.config)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte order mark, as editors on Windows write, is no error
    except FileNotFoundError:
        raise ValueError(f"--config {path}: no such file") from None
    except (OSError, UnicodeError) as exc:
        raise ValueError(f"--config {path}: cannot be read ({exc})") from None
    import json

    from hydromon.store import quantities

    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--config {path}: not JSON ({exc})") from None
    try:
        if isinstance(data, dict):  # magnitudes may carry their unit: "p_s": "12MPa"
            data = quantities.convert(data, quantities.CONFIG, "")
        return RigConfig.model_validate(data)
    except ValueError as exc:
        if not isinstance(exc, ValidationError):
            raise ValueError(f"--config {path}: {exc}") from None
        first = exc.errors()[0]
        where = ".".join(str(x) for x in first.get("loc", ())) or "the document"
        raise ValueError(f"--config {path}: {where}: {first.get('msg')} ({exc.error_count()} error(s))") from None


def constants_line(config, given: bool, suffix: str, recorded: bool = True) -> str:
    """Where a record's rig constants came from, for the commands' stderr header; ``recorded``:
    an MCAP holds a config for the rig (else the paper's constants were taken)."""
    if given:
        return f"rig constants from --config ({config.sample_rate:g} Hz)"
    if suffix == ".csv":
        return (f"rig constants: the paper's at {config.sample_rate:g} Hz (a CSV carries none; give yours with "
                "--config FILE)")
    if not recorded:
        return (f"rig constants: the paper's at {config.sample_rate:g} Hz (the recording holds no config for the "
                "rig; give yours with --config FILE)")
    return "rig constants as recorded"


def has_recorded_config(path, rig: str) -> bool:
    """Whether the MCAP at ``path`` holds a config of ``rig`` (metadata or a config message)."""
    from hydromon.store import mcap_read

    try:
        mcap_read.read_rig_config(str(path), rig)
    except ValueError:
        return False
    return True
