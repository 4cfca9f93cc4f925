"""Fleet files: which simulated rigs a ``hydromon sim`` node runs (JSON or TOML).

A fleet file is a table of shared settings and a list of rigs, e.g. in TOML::

    seed = 7                         # base of the per-rig noise seeds
    [config]                         # RigConfig fields shared by all rigs (SI), optional
    p_s = 12e6
    [[rigs]]
    id = "press-1"
    severity = 0.35                  # plant_sim.degradation.degrade, 0 new .. 1 fault
    profile = "paper-var:period=10"  # plant_sim.profiles.parse_profile
    noise = "realistic"              # none | realistic | stress | pct:F
    effects = { stribeck_friction = "40N", sensor_delay = 2 }
    [[rigs]]
    id = "press-2"
    table4 = 3                       # the paper's Table 4 group 1..5 as the plant
    params = { f_c = "30N" }         # PlantParams overrides, applied last

Effects are ``NAME = MAGNITUDE`` with the names of ``plant_sim.params.EFFECT_NAMES``
(:data:`EFFECT_FIELDS` gives the field and unit each sets); ``sensor_delay_loop = true``
puts the sensor delay inside the control loop. Every magnitude (effects, params, base,
config) is a number in SI or a text with its unit ("2.5um", "12MPa"), and must lie in its
sensible range (``hydromon.store.quantities``). Everything is validated here, at the edge:
a bad value raises ValueError naming it.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from hydromon.contract import RigConfig, valid_rig_id
from hydromon.store import quantities
from hydromon.store.magnitudes import parse as parse_magnitude
from plant_sim.degradation import degrade, degrade_relative, table4_group
from plant_sim.live import PlantFleet
from plant_sim.noise import noise_model
from plant_sim.params import EFFECT_NAMES, Controller, Effects, PlantParams
from plant_sim.profiles import parse_profile
from plant_sim.validation import brief_error

__all__ = [
    "EFFECT_FIELDS", "RigSpec", "FleetSpec", "parse_effect", "load_fleet", "default_fleet",
    "spread_fleet", "rig_seeds", "brief_error", "parse_controller", "effect_magnitude",
]

EFFECT_FIELDS = {
    "stribeck_friction": ("stribeck_F_s", "N"),
    "valve_saturation": ("x_max", "m"),
    "valve_dead_band": ("dead_band", "m"),
    "supply_pressure_sag": ("supply_sag", "Pa/(m^3/s)"),
    "entrained_air": ("air_fraction", "-"),
    "sensor_delay": ("sensor_delay", "samples"),
    "load_offset": ("load_offset", "N"),
}
"""Effect name -> (``plant_sim.params.Effects`` field it sets, unit of the magnitude)."""
assert set(EFFECT_FIELDS) == set(EFFECT_NAMES)


def parse_effect(text: str) -> tuple[str, float]:
    """``"NAME=MAGNITUDE"`` -> ``(NAME, MAGNITUDE in SI)``, e.g. ``"stribeck_friction=40N"``,
    ``"valve_dead_band=2.5um"`` (a bare number is SI; outside its sensible range it is refused)."""
    name, eq, value = text.partition("=")
    name = name.strip()
    if not eq:
        raise ValueError(f"effect {text!r}: expected NAME=MAGNITUDE")
    return name, effect_magnitude(name, value)


def effect_magnitude(name: str, value) -> float:
    """An effect's magnitude (a number in SI, or a text with its unit) in SI, checked."""
    _check_effect_name(name)
    return parse_magnitude(value, quantities.EFFECTS[name], name)


def parse_controller(text: str) -> Controller:
    """``"p"`` (the rig constants' proportional loop) or ``"pi:ki=K_I,kff=K_FF"`` (K_I [1/s],
    K_FF [s]; either may be left out) -> ``plant_sim.params.Controller``."""
    kind, _, rest = text.partition(":")
    kind = kind.strip()
    if kind == "p" and not rest.strip():
        return Controller()
    if kind != "pi":
        raise ValueError(f"controller {text!r}: expected p or pi:ki=K_I,kff=K_FF")
    fields = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        key = {"ki": "K_i", "kff": "K_ff"}.get(key.strip())
        if key is None or not eq:
            raise ValueError(f"controller {text!r}: {item!r} is not ki=K_I or kff=K_FF")
        try:
            fields[key] = parse_magnitude(value, quantities.CONTROLLER[key], key.replace("K_", "k").lower())
        except ValueError as exc:
            raise ValueError(f"controller {text!r}: {exc}") from None
    try:
        return Controller(**fields)
    except ValidationError as exc:
        raise ValueError(f"controller {text!r}: {brief_error(exc)}") from None


def _check_effect_name(name: str) -> None:
    if name not in EFFECT_FIELDS:
        raise ValueError(f"unknown effect {name!r}; choose from {', '.join(EFFECT_NAMES)}")


class RigSpec(BaseModel):
    """One simulated rig.

    Attributes
    ----------
    id : str
        Rig id, 1-64 chars of ``[A-Za-z0-9_-]`` (used in keys and file names).
    severity : float, optional
        Degradation in [0, 1] (``plant_sim.degradation.degrade``); exclusive with table4.
    table4 : int, optional
        The paper's Table 4 group 1..5 as the plant.
    params : dict
        ``PlantParams`` fields overriding the plant (SI), applied last.
    profile : str
        Command profile spec (``plant_sim.profiles.parse_profile``).
    seed : int, optional
        Noise seed; default derived from the fleet seed and the rig's position.
    noise : str
        Noise model: none, realistic, stress or pct:F.
    effects : dict
        Effect name -> magnitude in the unit of :data:`EFFECT_FIELDS`.
    sensor_delay_loop : bool
        The sensor delay acts inside the control loop too.
    base : dict
        The rig's own healthy plant: ``PlantParams`` fields overriding Table 1 (SI). With a
        severity the rig degrades relative to this plant (``degrade_relative``), as a rig of
        another size degrades from itself; without, severities follow the reference rig's
        absolute Table 3 values.
    config : dict
        ``RigConfig`` fields overriding the fleet's shared constants for this rig (SI).
    controller : str
        ``p``: the rig constants' proportional loop; ``pi:ki=K_I,kff=K_FF``: a digital PI loop
        with feed-forward (``plant_sim.params.Controller``: K_I [1/s], K_FF [s]).
    publish_u : bool, optional
        Publish the valve drive ``u`` [V] in every sample; default: when the controller is not
        the proportional loop (a monitor cannot know such a loop's drive otherwise).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str
    severity: float | None = None
    table4: int | None = None
    params: dict[str, float] = Field(default_factory=dict)
    profile: str = "paper-var"
    seed: int | None = None
    noise: str = "none"
    effects: dict[str, float] = Field(default_factory=dict)
    sensor_delay_loop: bool = False
    base: dict[str, float] = Field(default_factory=dict)
    config: dict[str, float] = Field(default_factory=dict)
    controller: str = "p"
    publish_u: bool | None = None

    @field_validator("id")
    @classmethod
    def _id(cls, v: str) -> str:
        if not valid_rig_id(v):
            raise ValueError(f"rig id {v!r} must be 1-64 chars of [A-Za-z0-9_-]")
        return v

    @field_validator("severity")
    @classmethod
    def _severity(cls, v):
        if v is not None and not (0.0 <= v <= 1.0):
            raise ValueError(f"severity {v!r} must lie in [0, 1]")
        return v

    @field_validator("table4")
    @classmethod
    def _table4(cls, v):
        if v is not None and v not in range(1, 6):
            raise ValueError(f"table4 group {v!r} must be 1..5")
        return v

    @field_validator("params", "base", mode="before")
    @classmethod
    def _params_si(cls, v, info):
        return quantities.convert(v, quantities.PLANT, f"{info.field_name} ") if isinstance(v, dict) else v

    @field_validator("config", mode="before")
    @classmethod
    def _config_si(cls, v):
        return quantities.convert(v, quantities.CONFIG, "config ") if isinstance(v, dict) else v

    @field_validator("params", "base")
    @classmethod
    def _params(cls, v):
        unknown = sorted(set(v) - set(PlantParams.model_fields))
        if unknown:
            raise ValueError(f"unknown plant parameter(s) {', '.join(map(repr, unknown))}; "
                             f"choose from {', '.join(PlantParams.model_fields)}")
        return v

    @field_validator("config")
    @classmethod
    def _config(cls, v):
        unknown = sorted(set(v) - set(RigConfig.model_fields))
        if unknown:
            raise ValueError(f"unknown rig constant(s) {', '.join(map(repr, unknown))}; "
                             f"choose from {', '.join(RigConfig.model_fields)}")
        return v

    @field_validator("controller")
    @classmethod
    def _controller(cls, v):
        parse_controller(v)
        return v

    @field_validator("effects", mode="before")
    @classmethod
    def _effects(cls, v):
        if isinstance(v, (list, tuple)):  # ["NAME=MAG", ...] as on the command line
            return dict(parse_effect(item) for item in v)
        if isinstance(v, dict):
            return {name: effect_magnitude(name, mag) for name, mag in v.items()}
        return v

    @field_validator("profile")
    @classmethod
    def _profile(cls, v):
        parse_profile(v)  # raises ValueError naming the bad spec
        return v

    @field_validator("noise")
    @classmethod
    def _noise(cls, v):
        noise_model(v)
        return v

    @model_validator(mode="after")
    def _check(self) -> "RigSpec":
        if self.severity is not None and self.table4 is not None:
            raise ValueError(f"rig {self.id!r}: give severity or table4, not both")
        if self.table4 is not None and self.base:
            raise ValueError(f"rig {self.id!r}: a Table 4 group is the reference rig's plant; give base or table4")
        self.plant()
        self.effects_model()
        return self

    def rig_config(self, shared: RigConfig | None = None) -> RigConfig:
        """The rig's constants: the fleet's ``shared`` ones with this rig's ``config`` fields."""
        shared = shared or RigConfig()
        if not self.config:
            return shared
        try:
            return RigConfig(**{**shared.model_dump(), **self.config})
        except ValidationError as exc:
            raise ValueError(f"rig {self.id!r} config: {brief_error(exc)}") from None

    def healthy(self) -> PlantParams:
        """The rig's plant when new: Table 1 with ``base``."""
        try:
            return PlantParams(**{**PlantParams().model_dump(), **self.base})
        except ValidationError as exc:
            raise ValueError(f"rig {self.id!r} base: {brief_error(exc)}") from None

    def plant(self, shared: RigConfig | None = None) -> PlantParams:
        """The rig's plant: a Table 4 group, or degraded to severity (relative to ``base`` when
        given), or its healthy plant; then ``params``. ``shared``: the fleet's constants."""
        if self.table4 is not None:
            plant = table4_group(self.table4)
        elif self.severity is not None and self.base:
            plant = degrade_relative(self.severity, self.healthy(), self.rig_config(shared))
        elif self.severity is not None:
            plant = degrade(self.severity)
        else:
            plant = self.healthy()
        try:
            return PlantParams(**{**plant.model_dump(), **self.params})
        except ValidationError as exc:
            raise ValueError(f"rig {self.id!r} params: {brief_error(exc)}") from None

    def controller_model(self) -> Controller:
        """The rig's ``plant_sim.params.Controller``."""
        return parse_controller(self.controller)

    @property
    def publishes_u(self) -> bool:
        """Whether the rig publishes its valve drive u in each sample."""
        return self.controller_model().digital if self.publish_u is None else self.publish_u

    def effects_model(self) -> Effects:
        """The rig's ``plant_sim.params.Effects``."""
        fields: dict = {}
        for name, mag in self.effects.items():
            field, _unit = EFFECT_FIELDS[name]
            if field == "sensor_delay":
                if mag != int(mag) or mag < 0:
                    raise ValueError(f"rig {self.id!r}: sensor_delay {mag!r} must be a whole number of samples >= 0")
                mag = int(mag)
            fields[field] = mag
        fields["sensor_delay_in_loop"] = self.sensor_delay_loop
        try:
            return Effects(**fields)
        except ValidationError as exc:
            raise ValueError(f"rig {self.id!r} effects {self.effects}: {brief_error(exc)}") from None


def rig_seeds(seed: int, n: int) -> list[int]:
    """n distinct, deterministic noise seeds derived from one base seed."""
    return [int(s) for s in np.random.SeedSequence(seed).generate_state(n)]


class FleetSpec(BaseModel):
    """A fleet: shared rig constants, a base seed and the rigs (ids unique)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    config: RigConfig = Field(default_factory=RigConfig)
    seed: int = 0
    rigs: list[RigSpec] = Field(min_length=1)

    @field_validator("config", mode="before")
    @classmethod
    def _config_si(cls, v):
        return quantities.convert(v, quantities.CONFIG, "config ") if isinstance(v, dict) else v

    @model_validator(mode="after")
    def _unique(self) -> "FleetSpec":
        seen = set()
        for r in self.rigs:
            if r.id in seen:
                raise ValueError(f"rig id {r.id!r} appears twice")
            seen.add(r.id)
        return self

    @property
    def ids(self) -> list[str]:
        return [r.id for r in self.rigs]

    def seeds(self) -> list[int]:
        """Each rig's noise seed: its own, else derived from the fleet seed."""
        derived = rig_seeds(self.seed, len(self.rigs))
        return [r.seed if r.seed is not None else d for r, d in zip(self.rigs, derived)]

    def with_overrides(self, **fields) -> "FleetSpec":
        """The same fleet with the given RigSpec fields set on every rig (None = keep)."""
        fields = {k: v for k, v in fields.items() if v is not None}
        if not fields:
            return self
        if "severity" in fields:  # a severity replaces a Table 4 plant
            fields.setdefault("table4", None)
        rigs = [RigSpec(**{**r.model_dump(), **fields}) for r in self.rigs]
        return FleetSpec(config=self.config, seed=self.seed, rigs=rigs)

    def configs(self) -> list[RigConfig]:
        """Each rig's constants (the shared ones with its own overrides)."""
        return [r.rig_config(self.config) for r in self.rigs]

    def build(self, substeps: int | None = None) -> PlantFleet:
        """The ``PlantFleet`` simulating these rigs."""
        kw = {} if substeps is None else {"substeps": substeps}
        configs = self.configs()
        return PlantFleet(
            configs,
            [r.plant(self.config) for r in self.rigs],
            [parse_profile(r.profile) for r in self.rigs],
            [r.effects_model() for r in self.rigs],
            [noise_model(r.noise, c) for r, c in zip(self.rigs, configs)],
            self.seeds(),
            controllers=[r.controller_model() for r in self.rigs],
            **kw,
        )


def load_fleet(path: str | Path) -> FleetSpec:
    """Read a fleet file (``.toml``, else JSON); ValueError names what is wrong."""
    path = Path(path)
    text = path.read_text()
    try:
        data = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not a TOML fleet file ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a JSON fleet file ({exc}); a fleet file is .toml or .json") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a fleet file is a table with a 'rigs' list")
    try:
        return FleetSpec.model_validate(data)
    except ValidationError as exc:
        raise ValueError(f"{path}: {brief_error(exc)}") from None


def default_fleet(profile: str = "paper-var", noise: str = "none", seed: int = 0) -> FleetSpec:
    """The paper's five Table 4 rigs ``table4-g1`` .. ``table4-g5`` under ``profile``."""
    return FleetSpec(seed=seed, rigs=[RigSpec(id=f"table4-g{g}", table4=g, profile=profile, noise=noise)
                                      for g in range(1, 6)])


def spread_fleet(n: int, *, seed: int | None = None, profile: str = "paper-var", noise: str = "none",
                 prefix: str = "rig") -> FleetSpec:
    """n rigs ``rig-0000`` ..: severities evenly over [0, 1], or uniform random with ``seed``."""
    if n < 1:
        raise ValueError(f"--rigs {n!r}: need at least one rig")
    if seed is None:
        sev = np.linspace(0.0, 1.0, n) if n > 1 else np.array([0.0])
    else:
        sev = np.random.default_rng(seed).uniform(0.0, 1.0, n)
    width = max(4, len(str(n - 1)))
    rigs = [RigSpec(id=f"{prefix}-{i:0{width}d}", severity=float(s), profile=profile, noise=noise)
            for i, s in enumerate(sev)]
    return FleetSpec(seed=seed or 0, rigs=rigs)


def true_grade(rig: RigSpec) -> str | None:
    """The grade a simulated rig really has: its Table 4 group's paper grade, the grade of
    its severity, or None when unknown (plant overrides, or an undegraded Table 1 plant with
    overrides)."""
    from plant_sim.degradation import TABLE4_PAPER_GRADES, grade_of_severity

    if rig.params:
        return None
    if rig.table4 is not None:
        return TABLE4_PAPER_GRADES[rig.table4]
    if rig.severity is not None:
        return grade_of_severity(rig.severity)
    return "health"
