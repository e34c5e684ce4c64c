"""Scenario files: which system to run, under which load, for how long, with which faults.

A scenario is a JSON file (or YAML when the path ends in .yaml/.yml), e.g. the paper's::

    {"system": "spring_mass_damper",
     "parameters": {"m": 10.0, "k": 100.0, "b": 0.5},
     "limits": {"k": [85, 105]},
     "load": {"kind": "constant", "value": 10.0},
     "duration": 120.0, "sample_rate": 100.0,
     "initial_state": {"k": 0.01},
     "fault": {"parameter": "k", "profile": [[0, 100], [5, 100], [50, 86.5], [100, 100]]},
     "sensors": {"noise": 0.01, "seed": 0}}

Several parts may age at once: ``"faults": [{"parameter": "k", "profile": ...}, {"parameter": "b", "profile":
...}]``, each parameter at most once; ``"fault"`` is the one-fault form of the same (not both in one file).

The load is one of ``{"kind": "constant", "value"}``, ``{"kind": "sines", "offset", "sines":
[{"amplitude", "frequency", "phase"}]}`` or ``{"kind": "random", "mean", "std", "bandwidth",
"seed"}``; load values are in the source's unit (N, V, ...), frequencies in Hz, phases in rad.
``"system"`` is a built-in system's name or a model file's path (relative to the scenario file; see
:mod:`ea_gym.model_files`). Parameters and limits are in SI (see ``SystemModel.units``), times in s, the sample rate in Hz,
initial states are energy variables (p in kg m/s or V s, q in m or C), and the sensor noise is a
standard deviation as a fraction of each measured signal's RMS.

:func:`load_scenario` validates everything and raises :class:`ScenarioError` listing, one line
each, the field path and what was expected.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, ValidationError

from ea_gym.degradation import PiecewiseLinearProfile, ProfileError
from ea_gym.documents import DocumentError, read_document
from ea_gym.model_files import is_model_file, load_system
from ea_gym.models import ParameterError, SystemModel
from ea_gym.numerics import MAX_LOAD, MAX_SAMPLES, MAX_SINE_TERMS, MAX_SINES

if TYPE_CHECKING:
    from ea_gym.loads import Load

# Strict: no silent conversion of "10" or true to a number.
Real = Annotated[float, Strict()]
Integer = Annotated[int, Strict()]
# a load value (its unit), bounded so that its powers stay finite
LoadValue = Annotated[float, Strict(), Field(ge=-MAX_LOAD, le=MAX_LOAD)]


#: problems a refusal's message lists before it counts the rest (each cut at 300 characters)
LISTED_PROBLEMS = 8


class ScenarioError(ValueError):
    """An invalid scenario; the message lists one ``<field.path>: <expected>`` line per problem."""

    problems: tuple[str, ...] = ()

    @classmethod
    def from_problems(cls, source: str, problems: Sequence[str]) -> ScenarioError:
        shown = [problem if len(problem) <= 300 else problem[:297] + "..." for problem in problems[:LISTED_PROBLEMS]]
        more = [f"... ({len(problems)} problems in all)"] if len(problems) > LISTED_PROBLEMS else []
        error = cls("\n  ".join([f"invalid scenario ({source}):", *shown, *more]))
        error.problems = tuple(problems)
        return error


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class ConstantLoadSpec(_Spec):
    """A constant load of ``value`` (N, V, ...)."""

    kind: Literal["constant"]
    value: LoadValue

    def make(self) -> Load:
        from ea_gym.loads import ConstantLoad  # the loads' numerical kernels, once a scenario is valid

        return ConstantLoad(level=self.value)


class SineSpec(_Spec):
    """amplitude (load unit) * sin(2 pi frequency (Hz) t + phase (rad))."""

    amplitude: LoadValue
    frequency: Real = Field(ge=0)
    phase: Real = 0.0


class SinesLoadSpec(_Spec):
    """offset + sum of sines (load unit; frequency in Hz, phase in rad)."""

    kind: Literal["sines"]
    offset: LoadValue = 0.0
    sines: list[SineSpec] = Field(max_length=MAX_SINES)

    def make(self) -> Load:
        from ea_gym.loads import Sine, SinesLoad

        return SinesLoad(self.offset, tuple(Sine(s.amplitude, s.frequency, s.phase) for s in self.sines))


class RandomLoadSpec(_Spec):
    """A band-limited random load (load unit; bandwidth in Hz) drawn from ``seed``."""

    kind: Literal["random"]
    mean: LoadValue
    std: Real = Field(ge=0, le=MAX_LOAD)
    bandwidth: Real = Field(gt=0)
    seed: Integer = Field(ge=0)

    def make(self) -> Load:
        from ea_gym.loads import RandomLoad

        return RandomLoad.draw(self.mean, self.std, self.bandwidth, np.random.default_rng(self.seed))


LoadSpec = Annotated[ConstantLoadSpec | SinesLoadSpec | RandomLoadSpec, Field(discriminator="kind")]
_LOAD_KINDS = ("constant", "sines", "random")


class FaultFields(_Spec):
    """The fault's fields: ``profile`` is a list of (time s, value in the parameter's SI unit)."""

    parameter: str
    profile: list[tuple[Real, Real]] = Field(min_length=1)


class SensorFields(_Spec):
    """Sensor noise std as a fraction of each measured signal's RMS, the load measurement's noise std as a fraction of
    the load's RMS (each over a step of the chain), and their seed."""

    noise: Real = Field(default=0.0, ge=0, lt=1)
    load_noise: Real = Field(default=0.0, ge=0, lt=1)
    seed: Integer = Field(default=0, ge=0)


class ScenarioSpec(_Spec):
    """The schema of a scenario file (checked field by field; cross-field checks are in load_scenario)."""

    system: str
    parameters: dict[str, Real] = {}
    limits: dict[str, tuple[Real, Real]] = {}
    load: LoadSpec
    duration: Real = Field(gt=0)
    sample_rate: Real = Field(default=100.0, gt=0)
    initial_state: dict[str, Real] = {}
    fault: FaultFields | None = None
    faults: list[FaultFields] | None = None
    sensors: SensorFields = SensorFields()


@dataclass(frozen=True)
class FaultSpec:
    """A fault: ``parameter``'s value follows ``profile`` (s -> the parameter's SI unit)."""

    parameter: str
    profile: PiecewiseLinearProfile


@dataclass(frozen=True)
class Scenario:
    """A validated scenario.

    Attributes:
        system: the system as named: a built-in's name or a model file's path.
        model: the model with the scenario's parameter and limit overrides applied.
        load_spec: the load's validated spec; :meth:`make_load` builds the load.
        duration: simulated time (s).
        sample_rate: sampling rate (Hz); duration * sample_rate is an integer.
        initial_state: energy variable of some storage elements at t = 0 (the rest are 0).
        faults: every degrading parameter with its profile (``"faults"``, or the one ``"fault"``), each
            parameter at most once; () without a fault.
        noise: sensor noise std as a fraction of each measured signal's RMS.
        load_noise: the load measurement's noise std as a fraction of the load's RMS (0: the chain reads the load
            exactly; the plant is driven by the true load either way).
        sensor_seed: seed of the sensor noise.
        source: the file path, or "dict".
        spec: the whole validated file, for :meth:`to_dict`.
    """

    system: str
    model: SystemModel
    load_spec: ConstantLoadSpec | SinesLoadSpec | RandomLoadSpec
    duration: float
    sample_rate: float
    initial_state: dict[str, float]
    faults: tuple[FaultSpec, ...]
    noise: float
    load_noise: float
    sensor_seed: int
    source: str
    spec: ScenarioSpec = field(repr=False)

    @property
    def fault(self) -> FaultSpec | None:
        """The first of :attr:`faults` (the one fault of a single-fault scenario), None without a fault."""
        return self.faults[0] if self.faults else None

    @property
    def faulty_parameters(self) -> tuple[str, ...]:
        """The parameters of :attr:`faults`, in their order."""
        return tuple(fault.parameter for fault in self.faults)

    @property
    def n_samples(self) -> int:
        """Number of sampling intervals in [0, duration]."""
        return int(round(self.duration * self.sample_rate))

    def times(self) -> np.ndarray:
        """The n_samples + 1 sample times 0, 1/sample_rate, ..., duration (s)."""
        return np.arange(self.n_samples + 1) / self.sample_rate

    def make_load(self) -> Load:
        return self.load_spec.make()

    def parameters_at(self, t: np.ndarray) -> np.ndarray:
        """Parameter values at times t (s): shape t.shape + (n_parameters,), ``model.parameter_names`` order."""
        t = np.asarray(t, dtype=float)
        nominal = self.model.parameter_vector()
        values = np.broadcast_to(nominal, t.shape + nominal.shape).copy()
        for fault in self.faults:
            values[..., self.model.parameter_names.index(fault.parameter)] = fault.profile.value(t)
        return values

    def true_end_of_life(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """The ground-truth End of Life (s) of every faulty parameter with safe limits, seen from times t (s), shaped like
        t: where its profile's current trend meets the limit it heads for (``PiecewiseLinearProfile.trend_end_of_life``),
        inf where the trend is flat, t itself where the value is at or beyond a limit. Its RUL is this minus t."""
        limits = self.model.safe_limits
        return {fault.parameter: fault.profile.trend_end_of_life(t, limits[fault.parameter]) for fault in self.faults if fault.parameter in limits}

    def initial_state_vector(self) -> np.ndarray:
        """Initial energy variables in ``model.state_names`` order (0 = at rest)."""
        return np.array([self.initial_state.get(name, 0.0) for name in self.model.state_names], dtype=float)

    def to_dict(self) -> dict[str, Any]:
        """The validated scenario as JSON-ready data; load_scenario(to_dict()) gives it back."""
        return self.spec.model_dump(mode="json", exclude_none=True)


def _field_path(loc: Sequence[str | int]) -> str:
    path = ""
    for i, part in enumerate(loc):
        # A discriminated union puts the tag in the path (load.sines.offset); drop it.
        if i == 1 and loc[0] == "load" and part in _LOAD_KINDS:
            continue
        path += f"[{part}]" if isinstance(part, int) else (f".{part}" if path else str(part))
    return path


def _pydantic_problems(error: ValidationError) -> list[str]:
    problems = []
    for err in error.errors():
        path = _field_path(err["loc"])
        if err["type"] in ("union_tag_invalid", "union_tag_not_found"):
            got = f"got {err['ctx']['tag']!r}" if err["type"] == "union_tag_invalid" else "missing"
            problems.append(f"{path}.kind: expected one of {', '.join(map(repr, _LOAD_KINDS))} ({got})")
        elif err["type"] == "missing" or isinstance(err["input"], (Mapping, list)):
            problems.append(f"{path}: {err['msg']}")
        else:
            problems.append(f"{path}: {err['msg']} (got {err['input']!r})")
    return problems


def load_scenario(source: str | os.PathLike[str] | Mapping[str, Any], system: str | SystemModel | None = None) -> Scenario:
    """Read (from a JSON/YAML file, or a mapping) and validate a scenario; raises ScenarioError.

    The scenario's ``"system"`` is a built-in name or a model file's path, relative to the scenario
    file (to the working directory for a mapping); ``system``, when given, replaces it (a name, a
    path relative to the working directory, or a model).
    """
    if isinstance(source, Mapping):
        name, data = "dict", dict(source)
    else:
        name = os.fspath(source)
        try:
            data = read_document(name)
        except DocumentError as exc:
            raise ScenarioError.from_problems(name, [str(exc)]) from None
        if not isinstance(data, dict):
            raise ScenarioError.from_problems(name, [f"the top level must be an object, got {type(data).__name__}"])
    try:
        spec = ScenarioSpec.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError.from_problems(name, _pydantic_problems(exc)) from None
    named, base = (system, None) if system is not None else (spec.system, None if isinstance(source, Mapping) else Path(name).parent)
    try:
        model = load_system(named, base=base)
    except ParameterError as exc:
        raise ScenarioError.from_problems(name, [f"system: {exc}"]) from None
    if isinstance(named, str) and is_model_file(named):  # to_dict's scenario finds the file from anywhere
        spec = spec.model_copy(update={"system": str((Path(base or ".") / named).resolve())})

    problems: list[str] = []
    try:
        model = model.with_overrides(spec.parameters, spec.limits)
        model.check_resolved(spec.sample_rate, "sample_rate")
    except ParameterError as exc:
        problems.append(str(exc))
    resolved = not problems
    problems += _sampling_problems(spec)
    for key in spec.initial_state:
        if key not in model.state_names:
            problems.append(
                f"initial_state.{key}: unknown state {key!r} for system {model.name!r}; "
                f"valid states are {list(model.state_names)}"
            )
    faults, fault_problems = _faults(model, spec, spec.sample_rate if resolved else None)
    problems += fault_problems
    if problems:
        raise ScenarioError.from_problems(name, problems)

    return Scenario(
        system=named if isinstance(named, str) else named.name,
        model=model,
        load_spec=spec.load,
        duration=spec.duration,
        sample_rate=spec.sample_rate,
        initial_state=dict(spec.initial_state),
        faults=faults,
        noise=spec.sensors.noise,
        load_noise=spec.sensors.load_noise,
        sensor_seed=spec.sensors.seed,
        source=name,
        spec=spec,
    )


def _sampling_problems(spec: ScenarioSpec) -> list[str]:
    """The run's sample count (whole, at most MAX_SAMPLES, checked before anything is allocated) and every load
    frequency below Nyquist."""
    problems = []
    samples = spec.duration * spec.sample_rate
    if samples > MAX_SAMPLES:
        problems.append(
            f"duration: duration * sample_rate = {samples:g} samples; at most {MAX_SAMPLES} per run "
            f"(e.g. {MAX_SAMPLES / spec.sample_rate:g} s at {spec.sample_rate:g} Hz)"
        )
    elif round(samples) < 1 or not math.isclose(samples, round(samples), rel_tol=1e-9, abs_tol=1e-9):
        problems.append(
            f"duration: duration * sample_rate = {samples!r} must be a whole number (>= 1) of samples"
        )
    if isinstance(spec.load, RandomLoadSpec) and not spec.load.bandwidth < spec.sample_rate / 2:
        problems.append(
            f"load.bandwidth: {spec.load.bandwidth!r} Hz must be below the Nyquist frequency "
            f"sample_rate / 2 = {spec.sample_rate / 2!r} Hz"
        )
    if isinstance(spec.load, SinesLoadSpec) and samples * len(spec.load.sines) > MAX_SINE_TERMS:
        problems.append(
            f"load.sines: {len(spec.load.sines)} sines over {samples:g} samples are {samples * len(spec.load.sines):g} sine terms; "
            f"at most {MAX_SINE_TERMS} per run (fewer sines or a shorter run)"
        )
    elif isinstance(spec.load, SinesLoadSpec):
        for i, sine in enumerate(spec.load.sines):
            if not sine.frequency < spec.sample_rate / 2:
                problems.append(
                    f"load.sines[{i}].frequency: {sine.frequency!r} Hz must be below the Nyquist frequency "
                    f"sample_rate / 2 = {spec.sample_rate / 2!r} Hz"
                )
    return problems


def _faults(model: SystemModel, spec: ScenarioSpec, sample_rate: float | None) -> tuple[tuple[FaultSpec, ...], list[str]]:
    """The scenario's faults (``"fault"``, or the list ``"faults"``) checked: one field of the two, each parameter once,
    each profile as :func:`_fault` checks it; with ``sample_rate`` (None: the model is not resolved even at its nominal
    values, already said), the model's fastest mode at every breakpoint of every profile, all the faulty parameters at
    their values of that time."""
    if spec.fault is not None and spec.faults is not None:
        return (), ["faults: give either fault (one) or faults (a list of them), not both"]
    if spec.faults is None:
        listed, paths = ([spec.fault], ["fault"]) if spec.fault is not None else ([], [])
    else:
        listed, paths = list(spec.faults), [f"faults[{j}]" for j in range(len(spec.faults))]
    problems: list[str] = []
    first: dict[str, int] = {}
    for j, fields in enumerate(listed):
        if first.setdefault(fields.parameter, j) != j:
            problems.append(f"{paths[j]}.parameter: {fields.parameter!r} is already faulty ({paths[first[fields.parameter]]}); "
                            "expected each parameter at most once, its whole profile in one fault")
    if problems:
        return (), problems
    faults = []
    for fields, path in zip(listed, paths):
        fault, fault_problems = _fault(model, fields, path)
        problems += fault_problems
        if fault is not None:
            faults.append(fault)
    if not problems and sample_rate is not None:
        problems += _resolved_along(model, tuple(faults), paths, sample_rate)
    return (() if problems else tuple(faults)), problems


def _resolved_along(model: SystemModel, faults: tuple[FaultSpec, ...], paths: Sequence[str], sample_rate: float) -> list[str]:
    """The model's fastest mode resolved at every breakpoint of every (piecewise linear) profile, every faulty parameter at
    its value then; the first breakpoint that is not is named."""
    for fault, path in zip(faults, paths):
        for i, t in enumerate(fault.profile.times):
            values = {other.parameter: float(other.profile.value(np.array(t))) for other in faults}
            try:
                model.check_resolved(sample_rate, f"{path}.profile[{i}]", values)
            except ParameterError as exc:
                return [str(exc)]
    return []


def _fault(model: SystemModel, fields: FaultFields, path: str) -> tuple[FaultSpec | None, list[str]]:
    """A fault's parameter and profile checked, each problem named under ``path`` ("fault", "faults[1]")."""
    try:
        model.check_name(fields.parameter, f"{path}.parameter")
    except ParameterError as exc:
        return None, [str(exc)]
    problems = []
    for i, (_, value) in enumerate(fields.profile):
        try:
            model.check_near_nominal(fields.parameter, value, f"{path}.profile[{i}]")
        except ParameterError as exc:
            problems.append(str(exc))
    try:
        profile = PiecewiseLinearProfile(tuple(t for t, _ in fields.profile), tuple(v for _, v in fields.profile))
    except ProfileError as exc:
        where = f"{path}.profile" if exc.index is None else f"{path}.profile[{exc.index}]"
        return None, [*problems, f"{where}: {exc.reason}"]
    return (None if problems else FaultSpec(fields.parameter, profile)), problems
