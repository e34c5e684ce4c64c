"""Built-in systems: a bond graph with its nominal component values and safe limits.

``spring_mass_damper`` is the paper's system (Fig 6-7, Table 2), ``rlc_circuit`` its electrical
example (Fig 3-4) and ``dc_motor`` a motor driving a damped inertia (a GY element joins the
electrical and mechanical domains).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ea_gym.bondgraph.elements import Kind
from ea_gym.bondgraph.equations import StateSpaceModel
from ea_gym.bondgraph.graph import BondGraph


class ParameterError(ValueError):
    """A component value or safe limit that is unknown or outside its physical range."""


#: how far (as a factor either way) a scenario may move a parameter or a limit from the model's nominal value: the
#: model's time constants scale with its parameters, and a factor beyond this puts them decades away from the
#: sample period the model was built for (``"m": 1e-20`` made a 200 m displacement out of a 10 N load)
MAX_NOMINAL_RATIO = 1e3


@dataclass(frozen=True)
class SystemModel:
    """A physical system ready to simulate.

    Attributes:
        name: registry name.
        graph: the bond graph; parametrised elements are named after their parameter.
        nominal: nominal component value of every parametrised element (SI, see ``units``).
        safe_limits: (lower, upper) safe limits of the degradable parameters (same units).
        units: SI unit of every parameter and of the load.
        load_source: the source element driven by a scenario's load.
        nominal_load: the load's nominal value, its operating level (N, V, m/s, ...), e.g. Table 2's F = 10 N;
            0 for a zero-mean load (a road's vertical velocity).
        excitation_bandwidth: bandwidth (Hz) of the random loads that excite the system's dynamics
            (above its resonances) when fault databases and environments draw loads.
        description: one line for people.
        source_values: the constant value of every source but the load source (its unit, e.g. N, V).
        load_scale: the size of the random loads' variation (the load's unit): their std is 20 to 40 % of it;
            None: |nominal_load|, which must then not be 0.
    """

    name: str
    graph: BondGraph
    nominal: Mapping[str, float]
    safe_limits: Mapping[str, tuple[float, float]]
    units: Mapping[str, str]
    load_source: str
    nominal_load: float
    excitation_bandwidth: float
    description: str = ""
    source_values: Mapping[str, float] = field(default_factory=dict)
    load_scale: float | None = None

    def __post_init__(self) -> None:
        names = self.state_space.parameter_names
        sources = self.state_space.input_names
        if self.load_source not in sources:
            raise ParameterError(
                f"model {self.name!r}: load_source {self.load_source!r} is not a source; sources are {list(sources)}"
            )
        constant = sorted(set(sources) - {self.load_source})
        if sorted(self.source_values) != constant:
            raise ParameterError(
                f"model {self.name!r}: the sources other than the load source {constant} need constant values, "
                f"got values for {sorted(self.source_values)}"
            )
        for source, value in self.source_values.items():
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ParameterError(f"model {self.name!r}: source {source!r} = {value!r}; expected a finite constant")
        if not (math.isfinite(self.nominal_load) and 0 < self.random_load_scale < math.inf):
            raise ParameterError(
                f"model {self.name!r}: load of {self.load_source!r}: nominal {self.nominal_load!r}, scale {self.load_scale!r}; expected a "
                "finite nominal and a finite scale > 0 (a zero-mean load, nominal 0, needs its scale)"
            )
        missing = sorted(set(names) - set(self.nominal))
        if missing:
            raise ParameterError(f"model {self.name!r}: no nominal value for {missing}")
        for key, value in self.nominal.items():
            self.check_value(key, value, f"nominal value of {key!r}")
        for key, bounds in self.safe_limits.items():
            self.check_limits(key, bounds, f"safe limits of {key!r}")
            self.check_inside_limits(key, self.nominal[key], bounds, f"nominal value of {key!r}")

    @property
    def random_load_scale(self) -> float:
        """The size of the random loads' variation (the load's unit): ``load_scale``, else |``nominal_load``|."""
        return abs(self.nominal_load) if self.load_scale is None else self.load_scale

    @cached_property
    def state_space(self) -> StateSpaceModel:
        return StateSpaceModel(self.graph)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.state_space.parameter_names

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.state_space.state_names

    @property
    def rco_elements(self) -> tuple[str, ...]:
        """The R, C and I elements: the components whose EA enters the EAI sum (eq 5)."""
        return tuple(self.graph.names([Kind.R, Kind.C, Kind.I]))

    @property
    def load_index(self) -> int:
        """The load source's position among ``state_space.input_names``."""
        return self.state_space.input_names.index(self.load_source)

    def constant_inputs(self) -> np.ndarray:
        """The sources' constant values in ``state_space.input_names`` order, 0 at the load source, (n_inputs,):
        an input matrix times it is what the constant sources add."""
        return np.array([self.source_values.get(name, 0.0) for name in self.state_space.input_names])

    def source_inputs(self, load: np.ndarray, load_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every source's value and time derivative, (..., n_inputs) in ``state_space.input_names`` order,
        from the load source's (...): the other sources hold their constant ``source_values``."""
        load, load_rate = np.asarray(load, dtype=float), np.asarray(load_rate, dtype=float)
        if not self.source_values:
            return load[..., None], load_rate[..., None]
        values = self.constant_inputs()
        u = np.broadcast_to(values, load.shape + values.shape).copy()
        du = np.zeros(load_rate.shape + values.shape)
        u[..., self.load_index], du[..., self.load_index] = load, load_rate
        return u, du

    def parameter_vector(self, values: Mapping[str, float] | None = None) -> np.ndarray:
        """Nominal values, with ``values`` overriding some, as an array in ``parameter_names`` order."""
        merged = {**self.nominal, **(values or {})}
        return np.array([merged[name] for name in self.parameter_names], dtype=float)

    def check_name(self, name: str, what: str) -> None:
        if name not in self.parameter_names:
            raise ParameterError(
                f"{what}: unknown parameter {name!r} for system {self.name!r}; "
                f"valid parameters are {list(self.parameter_names)}"
            )

    def check_value(self, name: str, value: float, what: str) -> None:
        """Every component value must be finite and strictly positive."""
        self.check_name(name, what)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(
                f"{what}: {name!r} = {value!r} is outside its physical range; expected a finite value > 0 "
                f"{self.units.get(name, '')}".rstrip()
            )

    def check_limits(self, name: str, bounds: tuple[float, float], what: str) -> None:
        self.check_name(name, what)
        lower, upper = bounds
        self.check_value(name, lower, f"{what} (lower)")
        self.check_value(name, upper, f"{what} (upper)")
        if not lower < upper:
            raise ParameterError(f"{what}: lower limit {lower} must be below upper limit {upper}")

    def check_degradable(self) -> None:
        """Refuse a model with no degradable parameter (no safe limits): the PHM chain and the environments isolate
        and track the parameters that have limits."""
        if not self.safe_limits:
            raise ParameterError(
                f"system {self.name!r} has no degradable parameter: the PHM chain and the environments need at least one "
                "parameter with safe limits ('limits' in the model file or the scenario)"
            )

    def check_near_nominal(self, name: str, value: float, what: str) -> None:
        """A positive finite value within MAX_NOMINAL_RATIO of the parameter's nominal value, either way."""
        self.check_value(name, value, what)
        nominal = self.nominal[name]
        if not nominal / MAX_NOMINAL_RATIO <= value <= nominal * MAX_NOMINAL_RATIO:
            raise ParameterError(
                f"{what}: {name!r} = {value!r} is more than a factor {MAX_NOMINAL_RATIO:g} from its nominal {nominal:g} "
                f"{self.units.get(name, '')}".rstrip() + f"; expected a value in [{nominal / MAX_NOMINAL_RATIO:g}, "
                f"{nominal * MAX_NOMINAL_RATIO:g}] (further away the model's time constants leave the range its sample "
                "period resolves)"
            )

    def fastest_mode(self, values: Mapping[str, float] | None = None) -> float:
        """max |lambda| over the eigenvalues of the state matrix (1/s) at the nominal values (``values`` overriding
        some); inf when the matrix overflows."""
        return _fastest_mode(self.state_space, self.parameter_vector(values))

    def check_resolved(self, sample_rate: float, what: str, values: Mapping[str, float] | None = None) -> None:
        """The model's fastest mode resolved at ``sample_rate`` (Hz), at the nominal values (``values`` overriding some).

        The rule: every eigenvalue lambda of the state matrix A has |lambda| < pi * sample_rate, i.e. each mode's natural
        frequency |lambda| / 2 pi lies below the Nyquist frequency sample_rate / 2 (a real mode's time constant above
        1 / (pi * sample_rate)). The plant's discretization (a matrix exponential) is stable at any step, but a faster
        mode aliases or settles between two samples, out of reach of the sampled powers (EA), the monitor and the
        detection, and the exponential's round-off grows with |lambda| h: ``m: 1e-20`` in a model file (|lambda| h = 5e17
        at 100 Hz) gave a 200 m displacement out of a 10 N load. The built-ins and the example model files stay below
        0.2 at 100 Hz.

        Raises:
            ParameterError: naming the parameters that set the fastest mode (its sensitivity to them at least half the largest).
        """
        theta = self.parameter_vector(values)
        fastest, bound = self.fastest_mode(values), math.pi * sample_rate
        if fastest < bound:
            return
        names = self.parameter_names
        if math.isfinite(fastest):  # how much |lambda| moves with each value, one at a time (d log|lambda| / d log value)
            nudged = theta * (1.0 + 1e-4 * np.eye(len(names)))
            sensitivity = np.abs(np.log([_fastest_mode(self.state_space, row) / fastest for row in nudged]))
        else:  # A overflows: the value furthest from 1 in its SI unit
            sensitivity = np.abs(np.log(theta))
        order = [i for i in np.argsort(-sensitivity, kind="stable") if sensitivity[i] >= 0.5 * sensitivity.max()]
        culprits = " and ".join(f"{names[i]} = {theta[i]:g} {self.units.get(names[i], '')}".rstrip() for i in order)
        raise ParameterError(
            f"{what}: the model's fastest mode, |lambda| = {fastest:.3g} 1/s, set by {culprits}, is not resolved at {sample_rate:g} Hz; "
            f"expected |lambda| < pi * sample_rate = {bound:.4g} 1/s (each mode's frequency below the Nyquist frequency "
            f"{sample_rate / 2:g} Hz, a real mode's time constant above {1 / bound:.3g} s): change these values or the sample rate"
        )

    def check_inside_limits(self, name: str, value: float, bounds: tuple[float, float], what: str) -> None:
        """``value`` strictly inside the safe limits: a component at or beyond them has already failed."""
        lower, upper = bounds
        if not lower < value < upper:
            raise ParameterError(
                f"{what}: {name!r} = {value!r} is not inside its safe limits [{lower:g}, {upper:g}]; the nominal value "
                "must lie strictly between them"
            )

    def with_overrides(
        self,
        parameters: Mapping[str, float] | None = None,
        limits: Mapping[str, tuple[float, float]] | None = None,
    ) -> SystemModel:
        """A copy with some nominal values and safe limits replaced (both checked)."""
        for key, value in (parameters or {}).items():
            self.check_near_nominal(key, value, f"parameters.{key}")
        for key, bounds in (limits or {}).items():
            self.check_limits(key, bounds, f"limits.{key}")
            for end, bound in zip(("lower", "upper"), bounds):
                self.check_near_nominal(key, bound, f"limits.{key} ({end})")
        nominal = {**self.nominal, **(parameters or {})}
        safe_limits = {**self.safe_limits, **{k: (v[0], v[1]) for k, v in (limits or {}).items()}}
        for key in {*(parameters or {}), *(limits or {})} & set(safe_limits):
            self.check_inside_limits(key, nominal[key], safe_limits[key], f"parameters.{key}" if key in (parameters or {}) else f"limits.{key}")
        return replace(self, nominal=nominal, safe_limits=safe_limits)


def _fastest_mode(state_space: StateSpaceModel, theta: np.ndarray) -> float:
    """max |lambda| over the eigenvalues of the state matrix at parameters ``theta`` (1/s); inf when A overflows."""
    with np.errstate(all="ignore"):
        A = state_space.matrices(theta).A
    if not np.all(np.isfinite(A)):
        return math.inf
    return float(np.abs(np.linalg.eigvals(A)).max(initial=0.0))


def spring_mass_damper() -> SystemModel:
    """The paper's spring-mass-damper (Fig 6-7, Table 2): Se F -> 1-junction -> I m, C k, R b."""
    g = BondGraph()
    g.add("F", Kind.SE).add("v", Kind.ONE)
    g.add("m", Kind.I).add("k", Kind.C, c_form="stiffness").add("b", Kind.R)
    for element in ("m", "k", "b"):
        g.connect("v", element)
    g.connect("F", "v")
    return SystemModel(
        name="spring_mass_damper",
        graph=g,
        nominal={"m": 10.0, "k": 100.0, "b": 0.5},
        safe_limits={"k": (85.0, 105.0), "m": (9.0, 11.0), "b": (0.4, 0.6)},
        units={"m": "kg", "k": "N/m", "b": "N s/m", "F": "N"},
        load_source="F",
        nominal_load=10.0,
        excitation_bandwidth=2.0,
        description="Spring-mass-damper of the paper's Fig 6-7 and Table 2",
    )


def rlc_circuit() -> SystemModel:
    """The circuit of the paper's Fig 3-4: Se -> 1 (R1, L1) -> 0 (C1, R2)."""
    g = BondGraph()
    g.add("U", Kind.SE).add("i", Kind.ONE).add("u_c", Kind.ZERO)
    g.add("R1", Kind.R).add("L1", Kind.I).add("C1", Kind.C).add("R2", Kind.R)
    g.connect("U", "i").connect("i", "R1").connect("i", "L1").connect("i", "u_c")
    g.connect("u_c", "C1").connect("u_c", "R2")
    return SystemModel(
        name="rlc_circuit",
        graph=g,
        nominal={"R1": 2.0, "L1": 1.0, "C1": 0.01, "R2": 50.0},
        safe_limits={"R1": (1.6, 2.4), "L1": (0.9, 1.1), "C1": (0.008, 0.012), "R2": (40.0, 60.0)},
        units={"R1": "ohm", "L1": "H", "C1": "F", "R2": "ohm", "U": "V"},
        load_source="U",
        nominal_load=10.0,
        excitation_bandwidth=5.0,
        description="RLC circuit of the paper's Fig 3-4",
    )


def dc_motor() -> SystemModel:
    """A DC motor driving a damped inertia: Se V -> 1 (Ra, La) -> GY K -> 1 (J, bm)."""
    g = BondGraph()
    g.add("V", Kind.SE).add("i", Kind.ONE).add("K", Kind.GY).add("w", Kind.ONE)
    g.add("Ra", Kind.R).add("La", Kind.I).add("J", Kind.I).add("bm", Kind.R)
    g.connect("V", "i").connect("i", "Ra").connect("i", "La").connect("i", "K")
    g.connect("K", "w").connect("w", "J").connect("w", "bm")
    return SystemModel(
        name="dc_motor",
        graph=g,
        nominal={"Ra": 1.0, "La": 0.05, "K": 0.1, "J": 0.01, "bm": 0.001},
        safe_limits={"Ra": (0.8, 1.3), "La": (0.045, 0.055), "K": (0.09, 0.11), "J": (0.009, 0.011), "bm": (0.0008, 0.0015)},
        units={"Ra": "ohm", "La": "H", "K": "N m/A", "J": "kg m^2", "bm": "N m s/rad", "V": "V"},
        load_source="V",
        nominal_load=12.0,
        excitation_bandwidth=10.0,
        description="DC motor (armature Ra, La; torque constant K) driving a damped inertia (J, bm)",
    )


MODELS: dict[str, Callable[[], SystemModel]] = {
    "spring_mass_damper": spring_mass_damper,
    "rlc_circuit": rlc_circuit,
    "dc_motor": dc_motor,
}


def get_model(name: str) -> SystemModel:
    """The built-in model ``name``; the error lists the valid names."""
    try:
        return MODELS[name]()
    except KeyError:
        raise ParameterError(f"unknown system {name!r}; valid systems are {sorted(MODELS)}") from None
