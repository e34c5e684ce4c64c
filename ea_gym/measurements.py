"""Recorded measurements of a machine: the CSV format the PHM chain reads, checked before anything runs.

One header row, then one row per sample. Columns, in any order:

- ``t``: time (s), increasing, uniformly sampled at any rate (204.8 Hz too; any start);
- the load source's name (e.g. ``F``): the load's value (SI: N, V, m/s, ...);
- one per storage element, named after it: an I element's flow (a velocity in m/s, a current in A),
  a C element's displacement, its energy variable q (a spring's extension in m, a charge in C).

As spreadsheets write it: a UTF-8 byte-order mark is skipped; the delimiter is ``,`` or ``;`` (the one
the header holds more of), and in a ``;`` file a cell's decimal separator may be ``,`` (``1,5``). A
header cell may carry its unit in brackets, ``t [s]`` or ``v_m (m/s)``: the name is what stands before
it. A unit is checked against the column's SI unit (where the model's units name it: an I element in kg
measures m/s, in H A, in kg m^2 rad/s; a C element in N/m or m/N measures m, in F C, in N m/rad rad;
the load source's unit is the model's): the SI unit itself is read as is, a decimal prefix of it
(``ms``, ``mm/s``, ``kN``, ``mA``, ``um``) is converted to SI, anything else is refused naming the
column, the unit and what was expected.

``columns`` maps a model's column to the file's (``{"m": "v_body"}``; the command line's
``--columns m=v_body``); ``ignore`` names file columns left unread (``--ignore-columns T,comment``),
which may hold anything; any other column the model does not name is refused. ``sample_rate`` declares
the rate where the timestamps are rounded (256 Hz written to 1 ms): each t must then lie within the
timestamps' rounding (their last decimal) of the grid t0 + k / sample_rate, and the grid is taken as
the record's times.

Every cell is a plain decimal number (``1``, ``-0.25``, ``1.5e-3``); nothing else is read. The file must
be a regular file of at most :data:`MAX_BYTES` bytes and :data:`MAX_ROWS` samples, checked before it is
read whole. Every error names the file, the line (the header is line 1) and the column, and lists what
was found where a column is missing or unexpected.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ea_gym.documents import FileTooLargeError, NotRegularFileError, read_regular_file
from ea_gym.files import write_atomic
from ea_gym.models import ParameterError, SystemModel

#: the largest CSV read (bytes): about 6 hours at 100 Hz of a model with four storage elements
MAX_BYTES = 256 * 2**20
#: the most samples read
MAX_ROWS = 2_000_000
#: a sample's time may stray this fraction of the sampling period from the uniform grid
TIME_TOLERANCE = 0.01
#: most columns a measurement file's header may have, counted before any row is read (a model needs t, the load and
#: one column per state: at most ea_gym.model_files.MAX_STATES + 2)
MAX_COLUMNS = 1024
#: :func:`noise_estimate`'s process noise, a std per sample as a fraction of each signal's RMS: 1e-4 leaves a DC motor's
#: current under a multisine load (the load held linearly between samples) reading 0.28 % without noise, 3e-3 takes
#: 10 % of the noise into the states
PROCESS_NOISE = 1e-3
#: how many of a record's samples either side :func:`resampled`'s filter reaches (scipy's ``resample_poly``: 10 x the
#: larger of the up and down factors at the upsampled rate)
RESAMPLING_REACH = 10
#: the most column names a message lists
LISTED_COLUMNS = 12

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_UNIT = re.compile(r"(?P<name>.*?)\s*(?:\[(?P<bracket>[^\]]*)\]|\((?P<paren>[^)]*)\))")
_BOM = b"\xef\xbb\xbf"
#: decimal prefixes a unit may carry, and their factor to SI
PREFIXES = {"G": 1e9, "M": 1e6, "k": 1e3, "c": 1e-2, "m": 1e-3, "u": 1e-6, "\u00b5": 1e-6, "\u03bc": 1e-6, "n": 1e-9}
#: the SI units a column may be in (spaces, "*" and "\u00b7" between factors dropped): time, the signals, the loads
SI_UNITS = ("s", "m", "m/s", "rad", "rad/s", "A", "C", "V", "N", "Nm", "Pa", "W")
#: the signal's SI unit of a storage element, by its parameter's unit (spaces dropped)
SIGNAL_UNITS = {"I": {"kg": "m/s", "H": "A", "kgm^2": "rad/s", "kgm2": "rad/s"},
                "C": {"N/m": "m", "m/N": "m", "F": "C", "Nm/rad": "rad", "rad/(Nm)": "rad", "rad/Nm": "rad"}}


class MeasurementError(ValueError):
    """A measurement file that cannot be read as the format above; the message names the culprit."""


@dataclass(frozen=True)
class Measurements:
    """A machine's recorded signals.

    Attributes:
        t: sample times (s), uniform, increasing, (T,).
        load: the load source's value at every sample (SI), (T,).
        signals: measured signal of every storage element (I: flow, C: displacement q), in
            ``SystemModel.state_names`` order, (T, nx).
        rate: the sample rate (Hz) where it is known exactly (declared, or resampled to); None: the one ``t`` gives.
    """

    t: np.ndarray
    load: np.ndarray
    signals: np.ndarray
    rate: float | None = None

    @property
    def sample_period(self) -> float:
        """Mean sampling period (s)."""
        return 1.0 / self.rate if self.rate is not None else float(self.t[-1] - self.t[0]) / (len(self.t) - 1)

    @property
    def sample_rate(self) -> float:
        """Samples per second (Hz): the declared rate, else a whole number where it is one within 1e-6."""
        if self.rate is not None:
            return self.rate
        rate = 1.0 / self.sample_period
        return float(round(rate)) if abs(rate - round(rate)) <= 1e-6 * rate else rate

    @property
    def duration(self) -> float:
        """Time from the first sample to the last (s)."""
        return float(self.t[-1] - self.t[0])

    def first(self, seconds: float) -> Measurements:
        """The record's samples over its first ``seconds`` s (a healthy stretch to commission the machine on)."""
        end = round(seconds * self.sample_rate) + 1
        return Measurements(t=self.t[:end], load=self.load[:end], signals=self.signals[:end], rate=self.rate)


def measurement_columns(model: SystemModel) -> tuple[str, ...]:
    """The columns a measurement file of ``model`` has: t, the load source, every storage element."""
    return ("t", model.load_source, *model.state_names)


def column_units(model: SystemModel) -> dict[str, str | None]:
    """The SI unit of every column of :func:`measurement_columns` where the model's units tell it, else None."""
    elements = model.graph.elements
    units: dict[str, str | None] = {"t": "s", model.load_source: _si_unit(model.units.get(model.load_source))}
    for name in model.state_names:
        parameter_unit = _squeezed(model.units.get(name, ""))
        units[name] = SIGNAL_UNITS[elements[name].kind.value].get(parameter_unit)
    return units


def read_measurements(
    path: str | os.PathLike[str], model: SystemModel, max_bytes: int = MAX_BYTES, max_rows: int = MAX_ROWS, *,
    columns: Mapping[str, str] | None = None, ignore: Collection[str] = (), sample_rate: float | None = None,
) -> Measurements:
    """Read and check a measurement CSV of ``model``.

    Args:
        columns: model column -> the file's column it is read from (default: the same name).
        ignore: the file's columns left unread.
        sample_rate: the declared sample rate (Hz) of a record whose timestamps are rounded.

    Raises:
        MeasurementError: not a regular file, too large, a missing, extra or repeated column, a unit that is
            not the column's SI unit or a decimal prefix of it, a row of the wrong length, a cell that is not a
            finite number, times that do not increase uniformly (or stray from the declared rate's grid by more
            than their rounding), or a sample rate too low for the model's fastest mode (``SystemModel.check_resolved``).
    """
    path = Path(path)
    raw = _read_bytes(path, max_bytes)
    # at least the header and the samples: the csv module ends a line at LF, CR LF or a CR alone
    lines = raw.count(b"\n") + raw.count(b"\r") - raw.count(b"\r\n") + (not raw.endswith((b"\n", b"\r")))
    if lines - 1 > max_rows:
        raise MeasurementError(f"{path}: {lines - 1} lines after the header, more than the {max_rows} samples read; split the record")
    text = raw.decode("utf-8", errors="replace")
    head = re.split(r"\r\n|\r|\n", text, maxsplit=1)[0]
    delimiter = ";" if head.count(";") > head.count(",") else ","
    if head.count(delimiter) >= MAX_COLUMNS:  # before any row is split: each column costs every row a cell
        raise MeasurementError(f"{path}: the header has {head.count(delimiter) + 1} columns; a record has at most {MAX_COLUMNS}")
    rows = _rows(path, csv.reader(io.StringIO(text, newline=""), delimiter=delimiter))
    header = next(rows, None)
    if header is None:
        raise MeasurementError(f"{path}: empty file; expected a header row with columns {', '.join(measurement_columns(model))}")
    names, units = zip(*(_name_and_unit(cell) for cell in header)) if header else ((), ())
    order = _column_order(path, list(names), [cell.strip() for cell in header], model, columns or {}, ignore)
    factors = _unit_factors(path, model, [names[k] for k in order], [units[k] for k in order])
    table = _numbers(path, enumerate(rows, start=2), list(names), order, np.empty((max(lines - 1, 0), len(order))), delimiter == ";")
    if len(table) < 2:
        raise MeasurementError(f"{path}: {len(table)} sample(s); a record needs at least 2")
    for k, factor in enumerate(factors):
        if factor != 1.0:
            table[:, k] *= factor
    t = table[:, 0] if sample_rate is None else _declared_grid(path, table[:, 0], sample_rate)
    if sample_rate is None:
        _check_times(path, t)
    measurements = Measurements(t=t, load=table[:, 1], signals=table[:, 2:], rate=sample_rate)
    try:
        model.check_resolved(measurements.sample_rate, "sample rate")
    except ParameterError as error:
        raise MeasurementError(f"{path}: {error}") from None
    return measurements


def _read_bytes(path: Path, max_bytes: int) -> bytes:
    """The file's bytes without a UTF-8 byte-order mark; refused when not a regular file or too large."""
    try:
        raw = read_regular_file(path, max_bytes)
    except OSError as error:
        raise MeasurementError(f"{path}: cannot read the measurements ({error.strerror})") from None
    except NotRegularFileError:
        raise MeasurementError(f"{path}: measurements must be a regular file") from None
    except FileTooLargeError as error:
        read = f"more than the {max_bytes} bytes" if error.size is None else f"{error.size} bytes, more than the {max_bytes}"
        raise MeasurementError(f"{path}: {read} read; split the record") from None
    return raw.removeprefix(_BOM)


def _rows(path: Path, reader: Iterator[list[str]]) -> Iterator[list[str]]:
    """The CSV's rows; one the csv module cannot split (a cell past its size limit, a stray quote) refused at its line."""
    line = 1  # the line being read
    try:
        for row in reader:
            yield row
            line += 1
    except csv.Error as error:
        raise MeasurementError(f"{path}: line {line}: {error}; expected cells of plain decimal numbers") from None


def _name_and_unit(cell: str) -> tuple[str, str | None]:
    """A header cell's column name and the unit in its brackets (None without)."""
    match = _UNIT.fullmatch(cell.strip())
    if match is None:
        return cell.strip(), None
    return match["name"], (match["bracket"] if match["bracket"] is not None else match["paren"]).strip()


def _listed(names: Iterable[str]) -> str:
    """Column names for a message: the first LISTED_COLUMNS, then how many in all."""
    names = list(names)
    shown = ", ".join(repr(name) for name in names[:LISTED_COLUMNS])
    return shown + (f", ... ({len(names)} in all)" if len(names) > LISTED_COLUMNS else "") if names else "none"


def _column_order(
    path: Path, header: list[str], cells: list[str], model: SystemModel, columns: Mapping[str, str], ignore: Collection[str]
) -> list[int]:
    """Index in ``header`` of every column of :func:`measurement_columns`, read from ``columns``' file column where it maps one
    (found by its name or its whole header cell), refusing a column neither used nor in ``ignore``."""
    expected = measurement_columns(model)
    described = f"model {model.name} needs columns {', '.join(expected)}; found {_listed(header)}"
    index: dict[str, int] = {}
    for k, name in enumerate(header):
        if index.setdefault(name, k) != k:
            raise MeasurementError(f"{path}: column {name!r} appears twice ({described})")
    for name in columns:
        if name not in expected:
            raise MeasurementError(f"{path}: --columns {name}=...: {name!r} is not a column of model {model.name} ({', '.join(expected)})")
    for name in ignore:
        if name not in index and name not in cells:
            raise MeasurementError(f"{path}: --ignore-columns: no column {name!r} in the file (found {_listed(header)})")
    order: list[int] = []
    for name in expected:
        wanted = columns.get(name, name)
        found = index.get(wanted, cells.index(wanted) if wanted in cells else None)
        if found is None:
            how = f"--columns {name}=... names column {wanted!r}, absent" if name in columns else f"missing column {name!r}"
            raise MeasurementError(f"{path}: {how} ({described}; map another column to it with --columns {name}=COLUMN)")
        if found in order:
            twice = expected[order.index(found)]
            raise MeasurementError(f"{path}: column {header[found]!r} is read for both {twice} and {name}; expected one file column per model column")
        order.append(found)
    for k, name in enumerate(header):
        if k not in order and name not in ignore and cells[k] not in ignore:
            raise MeasurementError(f"{path}: unexpected column {name!r} ({described}; leave it unread with --ignore-columns {name})")
    return order


def _squeezed(unit: str) -> str:
    """A unit's text without spaces and the products' "*" or "\u00b7": "N m" and "N*m" read as "Nm"."""
    return re.sub(r"[\s*\u00b7]", "", unit)


def _si_unit(unit: str | None) -> str | None:
    """``unit`` where it is one of SI_UNITS (squeezed), else None."""
    squeezed = None if unit is None else _squeezed(unit)
    return squeezed if squeezed in SI_UNITS else None


def _unit_factor(unit: str) -> tuple[float, str] | None:
    """(factor to SI, SI unit) of an SI unit or a decimal prefix of one; None for anything else."""
    squeezed = _squeezed(unit)
    if squeezed in SI_UNITS:
        return 1.0, squeezed
    prefix, rest = squeezed[:1], squeezed[1:]
    return (PREFIXES[prefix], rest) if prefix in PREFIXES and rest in SI_UNITS else None


def _unit_factors(path: Path, model: SystemModel, names: list[str], units: list[str | None]) -> list[float]:
    """The factor to SI of every used column (1 where none is given), checked against the column's SI unit."""
    expected_units = column_units(model)
    factors = []
    for column, name, unit in zip(measurement_columns(model), names, units):
        if not unit:
            factors.append(1.0)
            continue
        expected = expected_units[column]
        read = _unit_factor(unit)
        if read is None or (expected is not None and read[1] != expected):
            wanted = f"{expected} or a decimal prefix of it" if expected is not None else f"an SI unit ({', '.join(SI_UNITS)}) or a prefix of one"
            raise MeasurementError(f"{path}: column {name!r}: unit {unit!r} is not read (the {column} column's); expected {wanted}, converted to SI")
        factors.append(read[0])
    return factors


def _numbers(
    path: Path, rows: Iterable[tuple[int, list[str]]], header: list[str], order: list[int], table: np.ndarray, decimal_comma: bool
) -> np.ndarray:
    """The ``order`` columns of every data row (with its line number) as floats into ``table`` (room for every line, at
    least), refusing anything that is not a finite decimal number (a "," read as the decimal point where
    ``decimal_comma``); the rows filled."""
    width = len(header)
    count = 0
    for line, row in rows:
        if not row:
            raise MeasurementError(f"{path}: line {line} is empty; expected {width} numbers")
        if len(row) != width:
            raise MeasurementError(f"{path}: line {line} has {len(row)} cells, the header {width}")
        for position, column in enumerate(order):
            text = row[column].strip()
            if decimal_comma:
                text = text.replace(",", ".", 1)
            if not _NUMBER.fullmatch(text):
                what = "an empty cell" if not text else f"{text[:20]!r}"
                raise MeasurementError(f"{path}: line {line}, column {header[column]!r}: {what} where a number is expected")
            number = float(text)
            if not np.isfinite(number):
                raise MeasurementError(f"{path}: line {line}, column {header[column]!r}: {text[:20]!r} overflows a float")
            table[count, position] = number
        count += 1
    return table[:count]


def _check_times(path: Path, t: np.ndarray) -> None:
    """``t`` increases, every interval within ``TIME_TOLERANCE`` of the median one (a gap, a repeated
    or a jittered sample is refused at its line)."""
    _check_increasing(path, t)
    step = np.diff(t)
    period = float(np.median(step))
    uneven = np.abs(step - period) > TIME_TOLERANCE * period
    if np.any(uneven):
        k = int(np.argmax(uneven)) + 1
        raise MeasurementError(
            f"{path}: line {k + 2}: t = {t[k]:.9g} s is {step[k - 1]:.6g} s after the line before, not the "
            f"sampling period {period:.6g} s: t must be uniformly sampled (a gap or jitter in the record; "
            "timestamps rounded to fewer decimals than the period needs: declare the rate with --sample-rate HZ)"
        )


def _check_increasing(path: Path, t: np.ndarray) -> None:
    step = np.diff(t)
    if np.any(step <= 0):
        k = int(np.argmax(step <= 0)) + 1
        raise MeasurementError(f"{path}: line {k + 2}: t = {t[k]:.9g} s does not increase (the line before has {t[k - 1]:.9g} s)")
    largest = float(np.max(np.abs(t)))
    period = float(np.median(step))
    if np.spacing(largest) > TIME_TOLERANCE * period / 2:  # a float that large cannot hold the period's fractions
        raise MeasurementError(
            f"{path}: column 't': times up to {largest:.6g} s are too large for their resolution: a float64 there resolves "
            f"{np.spacing(largest):.3g} s, more than {TIME_TOLERANCE / 2:g} of the {period:.3g} s sampling period; "
            "write the times from the record's start (t - t0)"
        )


def _timestamp_resolution(t: np.ndarray) -> float:
    """The step ``t`` is rounded to (s): 10^-d for the fewest decimals d <= 9 that write every t, else 0."""
    for decimals in range(10):
        scaled = t * 10.0**decimals
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-9 + 1e-12 * np.abs(scaled)):  # a float's round-off, not a decimal
            return 10.0**-decimals
    return 0.0


def _declared_grid(path: Path, t: np.ndarray, sample_rate: float) -> np.ndarray:
    """The grid t0 + k / ``sample_rate`` of the record's samples, each t within its rounding of it (the first one's
    rounding and its own: one resolution) plus ``TIME_TOLERANCE`` of a period."""
    _check_increasing(path, t)
    grid = t[0] + np.arange(len(t)) / sample_rate
    resolution = _timestamp_resolution(t)
    tolerance = resolution + TIME_TOLERANCE / sample_rate
    off = np.abs(t - grid) > tolerance
    if np.any(off):
        k = int(np.argmax(off))
        raise MeasurementError(
            f"{path}: line {k + 2}: t = {t[k]:.9g} s is {t[k] - grid[k]:+.6g} s off the declared {sample_rate:g} Hz grid "
            f"(t0 + k / {sample_rate:g} = {grid[k]:.9g} s), more than the timestamps' rounding ({resolution:g} s) allows: "
            "a gap in the record, or another rate"
        )
    return grid


def resampled(measurements: Measurements, sample_rate: float) -> Measurements:
    """The record at ``sample_rate`` (Hz), at least its own: band-limited (polyphase) interpolation of the load and the
    signals alike, so that the linear model relating them still holds.

    One filter on every channel: the load and the signals keep their relation through any linear time-invariant
    system (the model's), up to the filter's pass band (the record's Nyquist frequency). The filter reaches
    ``RESAMPLING_REACH`` samples of the record either way; the samples that close to its ends would need samples
    it does not have (padded, they were 1e-3 off; the reference model fitted to them rang for tens of seconds),
    so the result starts and ends that far inside."""
    from fractions import Fraction

    from scipy.signal import resample_poly

    ratio = Fraction(sample_rate / measurements.sample_rate).limit_denominator(100_000)
    up, down = ratio.numerator, ratio.denominator
    edge = math.ceil(RESAMPLING_REACH * max(up, down) / down)  # output samples within the filter's reach of the start
    last = (len(measurements.t) - 1) * up // down - edge
    if last - edge < 1:
        raise MeasurementError(f"{len(measurements.t)} samples: too short to resample (the filter reaches {RESAMPLING_REACH} either way)")
    channels = np.column_stack([measurements.load, measurements.signals])
    # scipy's default Kaiser beta of 5 leaves each polyphase branch's DC gain 7e-4 apart (a 10 N load came out
    # rippling by 7 mN at 204.8 -> 210 Hz); beta 14: 2e-6
    inside = resample_poly(channels, up, down, axis=0, window=("kaiser", 14.0))[edge : last + 1]
    t = measurements.t[0] + np.arange(edge, last + 1) / sample_rate
    return Measurements(t=t, load=inside[:, 0], signals=inside[:, 1:], rate=sample_rate)


def noise_estimate(
    measurements: Measurements, model: SystemModel, step: int, rounds: int = 6, parameters: Mapping[str, float] | None = None
) -> float:
    """The sensors' noise in the record as ``ChainTiming.noise`` (``ea_gym.phm.config``) reads it: a std, as a fraction of each
    signal's RMS over a step of ``step`` samples (the chain's 1 s), from the residuals of ``model`` itself.

    ``parameters`` replaces some of the model's values (SI; a commissioned machine's own, ``ea_gym.phm.commission``):
    the residuals of the machine it describes are what is left of the sensors' noise. A Kalman filter of the model
    (exact discretization, the measured load held linearly between samples, ``ea_gym.sensors.Sensors``' measurement
    model) runs on the record; its innovations e have the
    covariance C P C' + R, so the noise variance per signal and step is mean(e^2) - C P C' (covariance
    matching). Starting from 1 %, the level is set from that and the filter run again, ``rounds`` times:
    per signal and step the noise std over the signal's RMS, the median over the steps, the median over
    the signals. The process noise (``PROCESS_NOISE``) lets the filter follow what the load held linearly
    leaves. Whatever the model cannot explain (a machine off the values given, a wrong load, the load's own
    measurement noise) reads as noise: the model-fit test (``ea_gym.phm.fit``) says so. Measured on solve_ivp records of the quarter
    car of tests/test_measurements.py (10-15 Hz wheel hop at 100 Hz), spring_mass_damper, rlc_circuit and
    dc_motor at 0.5, 1 and 3 %: within 7 % of the truth (the 21-sample smoother this replaces read the
    quarter car's 1 % at 50 Hz as 4.9 %); without noise at most 0.11 % (dc_motor). About 1 s per 10,000
    samples of four states.
    """
    from ea_gym.bondgraph.simulation import HOLD_ORDER, discretize
    from ea_gym.sensors import Sensors

    signals = np.asarray(measurements.signals, dtype=float)
    samples, nx = signals.shape
    if samples < 2 * step or step < 2:
        raise ValueError(f"noise_estimate: {samples} samples, fewer than two steps of {step}")
    h = float(np.median(np.diff(measurements.t)))
    values = {**model.nominal, **(parameters or {})}
    theta = np.array([values[name] for name in model.parameter_names], dtype=float)
    mats = model.state_space.matrices(theta)
    step_matrices = discretize(mats.A, mats.B, h)
    inputs = model.source_inputs(np.asarray(measurements.load, dtype=float), np.zeros(samples))[0]
    # the load held linearly between samples: each interval's Taylor coefficients [u, u', 0, 0] (Gamma's order)
    held = np.concatenate([inputs[:-1], np.diff(inputs, axis=0) / h, np.zeros((samples - 1, (HOLD_ORDER - 2) * inputs.shape[1]))], axis=1)
    phi, drive = step_matrices.Phi, held @ step_matrices.Gamma.T
    # in the signals' own units, each over its RMS: C = 1, and any scale of signal keeps the filter conditioned
    scale = np.sqrt(np.mean(signals**2, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    to_signal = Sensors(model).gain(theta) / scale  # (nx,) the measurement model, diagonal, over the scale
    phi = to_signal[:, None] * phi / to_signal[None, :]
    drive = drive * to_signal
    normalized = signals / scale
    steps = samples // step
    shape = (steps, step, nx)
    rms = np.sqrt(np.mean(normalized[: steps * step].reshape(shape) ** 2, axis=1))  # (steps, nx)
    rms_per_sample = np.concatenate([np.repeat(rms, step, axis=0), np.repeat(rms[-1:], samples - steps * step, axis=0)])
    process = PROCESS_NOISE**2 * np.eye(nx)
    level = 0.01
    for _ in range(rounds):
        variance = np.maximum(level * rms_per_sample, 1e-6) ** 2  # (samples, nx)
        x, P = normalized[0].copy(), np.diag(variance[0])
        squared = np.zeros((samples, nx))
        predicted = np.zeros((samples, nx))
        for k in range(1, samples):
            x = phi @ x + drive[k - 1]
            P = phi @ P @ phi.T + process
            S = P + np.diag(variance[k])
            e = normalized[k] - x
            K = np.linalg.solve(S, P).T
            x = x + K @ e
            P = P - K @ P
            squared[k], predicted[k] = e**2, np.diag(S) - variance[k]
        # the first step left out: the filter's start-up
        excess = (squared - predicted)[step : steps * step].reshape(steps - 1, step, nx)
        moving = rms[1:] > 0  # a step where a signal is 0 throughout has no fraction to read
        if not moving.any():
            return 0.0
        fraction = np.sqrt(np.maximum(excess.mean(axis=1), 0.0)) / np.where(moving, rms[1:], 1.0)
        level = float(np.median([np.median(fraction[moving[:, j], j]) for j in range(nx) if moving[:, j].any()]))
    return level


def write_measurements(path: str | os.PathLike[str], model: SystemModel, measurements: Measurements) -> Path:
    """Write ``measurements`` of ``model`` as a CSV :func:`read_measurements` reads back exactly (atomically)."""
    table = np.column_stack([measurements.t, measurements.load, measurements.signals])
    header = ",".join(measurement_columns(model))
    return write_atomic(path, lambda tmp: np.savetxt(tmp, table, fmt="%.17g", delimiter=",", header=header, comments=""))
