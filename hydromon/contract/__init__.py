"""The shared vocabulary of hydromon: keys, payload models, rig constants, names and units.

A leaf package: it imports nothing else of hydromon, so the simulator (``plant_sim``), the
numerical core (``monitor``) and the shell all take their words from here.
"""

from hydromon.contract.keys import (
    DEFAULT_NAMESPACE, LEAVES, SAMPLE_LEAVES, RIG_ID_RE, check_namespace, config_key, frame_key, event_key, health_key, ranges_key, failover_key, liveliness_key,
    monitor_of_token, parse_rig_key, rig_key, rig_key_parts, sample_key, split_rig_key, valid_rig_id,
)
from hydromon.contract.names import CHANNELS, GRADES, PARAM_NAMES, PARAM_UNITS, PARAM_WORDS, SENSORS, UNKNOWN
from hydromon.contract.payloads import (
    DRIVE, DRIVE_LIMIT, EVENT_KINDS, FRAME_MAX, LEAF_MODELS, Event, Frame, RESTART_RUN, SAMPLE_COLUMNS, SAMPLE_LIMITS, SEQ_MAX, STATUSES, Health, Sample, schemas,
)
from hydromon.contract.rig import RigConfig

__all__ = [
    "DEFAULT_NAMESPACE", "LEAVES", "SAMPLE_LEAVES", "RIG_ID_RE", "check_namespace", "config_key", "frame_key", "event_key", "health_key", "ranges_key", "failover_key", "liveliness_key",
    "monitor_of_token", "parse_rig_key", "rig_key", "rig_key_parts", "sample_key", "split_rig_key", "valid_rig_id",
    "CHANNELS", "GRADES", "PARAM_NAMES", "PARAM_UNITS", "PARAM_WORDS", "SENSORS", "UNKNOWN",
    "DRIVE", "DRIVE_LIMIT", "EVENT_KINDS", "FRAME_MAX", "Event", "Frame", "LEAF_MODELS", "RESTART_RUN", "SAMPLE_COLUMNS", "SAMPLE_LIMITS", "SEQ_MAX", "STATUSES", "Health", "Sample",
    "schemas", "RigConfig",
]
