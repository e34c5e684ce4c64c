"""Exact discretization and simulation of a bond graph's linear model.

Between two samples the input is the cubic Hermite interpolant of its values and time derivatives at
both samples (error O(h^4), and local, so chunked and whole-run simulations agree), and the state is
propagated exactly through the matrix exponential of an augmented system. Parameters (degradation)
are held at their value at the middle of each sample interval, which keeps the error of a drifting
parameter second order in the step; efforts and flows at a sample use the parameters at that sample.

Everything is batched over N systems: arrays carry a leading system axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.polynomial import chebyshev

from ea_gym._kernels.expm import expm_batch, held_input_discretization
from ea_gym._kernels.propagation import propagate_states, simulate_hermite
from ea_gym._kernels.rows import changed_rows, replace_rows
from ea_gym.bondgraph.equations import StateSpaceModel
from ea_gym.threads import over_rows, single_threaded_blas

#: Batches of up to so many parameter rows are sorted in Python (a single environment's plant and reference).
FEW_ROWS = 8
#: Polynomial pieces per sample interval of the input: u(s) = sum_j w_j s^j / j!, j = 0..3.
HOLD_ORDER = 4


@dataclass(frozen=True)
class Discretization:
    """x[k+1] = Phi x[k] + Gamma w[k], where w[k] stacks the input's Taylor coefficients (HOLD_ORDER * nu)."""

    Phi: np.ndarray
    Gamma: np.ndarray


def expm(Z: np.ndarray) -> np.ndarray:
    """e^Z over the last two axes of Z (any leading batch shape), accurate to round-off.

    Equal to ``scipy.linalg.expm`` to ~1e-16 relative at the 1-norms of a discretization step (~1);
    scipy loops over a batch in Python, matrix by matrix, which this compiled loop avoids.
    """
    flat = np.ascontiguousarray(Z, dtype=float).reshape((-1,) + Z.shape[-2:])
    out = np.empty_like(flat)
    over_rows(lambda start, stop: expm_batch(flat[start:stop], out[start:stop]), len(flat))
    return out.reshape(Z.shape)


def discretize(A: np.ndarray, B: np.ndarray, h: float) -> Discretization:
    """Exact discretization of dx/dt = A x + B u for a cubic input over one step of ``h`` seconds (A (..., nx, nx)
    and B (..., nx, nu) of the same leading shape).

    The augmented state [x, u, u', u'', u'''] has a nilpotent input chain, so the top block row of its
    matrix exponential holds Phi = e^{Ah} and Gamma_j = int_0^h e^{A(h-s)} B s^j / j! ds.
    """
    nx, nu = A.shape[-1], B.shape[-1]
    batch = A.shape[:-2]  # B's too
    rows = math.prod(batch)
    # the augmented matrix is built, scaled and exponentiated in one compiled pass, Phi and Gamma written contiguous
    A = np.ascontiguousarray(A, dtype=float).reshape(rows, nx, nx)
    B = np.ascontiguousarray(B, dtype=float).reshape(rows, nx, nu)
    chain, h = _input_chain(nx, nu), float(h)
    Phi, Gamma = np.empty((rows, nx, nx)), np.empty((rows, nx, HOLD_ORDER * nu))

    def discretize_rows(start: int, stop: int) -> None:
        held_input_discretization(A[start:stop], B[start:stop], h, chain, Phi[start:stop], Gamma[start:stop])

    over_rows(discretize_rows, rows)
    return Discretization(Phi=Phi.reshape(batch + (nx, nx)), Gamma=Gamma.reshape(batch + (nx, HOLD_ORDER * nu)))


@cache
def _input_chain(nx: int, nu: int) -> np.ndarray:
    """The input rows of ``discretize``'s augmented matrix, (HOLD_ORDER nu, nx + HOLD_ORDER nu): each Taylor
    coefficient's derivative is the next one (an identity block), the last one's is 0."""
    rows = np.zeros((HOLD_ORDER * nu, nx + HOLD_ORDER * nu))
    for j in range(HOLD_ORDER - 1):
        rows[j * nu : (j + 1) * nu, nx + (j + 1) * nu : nx + (j + 2) * nu] = np.eye(nu)
    rows.flags.writeable = False
    return rows


def hermite_coefficients(u: np.ndarray, du: np.ndarray, h: float) -> np.ndarray:
    """Taylor coefficients [u, u', u'', u'''] at the start of every interval of the cubic Hermite interpolant.

    Args:
        u: input values at the samples, shape (..., T + 1, nu).
        du: their time derivatives (unit/s), same shape.
        h: sample period (s).

    Returns:
        shape (..., T, HOLD_ORDER * nu), ordered to match ``Discretization.Gamma``.
    """
    u0, u1, d0, d1 = u[..., :-1, :], u[..., 1:, :], du[..., :-1, :], du[..., 1:, :]
    slope = (u1 - u0) / h
    c2 = (3.0 * slope - 2.0 * d0 - d1) / h
    c3 = (d0 + d1 - 2.0 * slope) / h**2
    return np.concatenate([u0, d0, 2.0 * c2, 6.0 * c3], axis=-1)


def propagate(d: Discretization, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """Run the recursion x[k+1] = Phi[k] x[k] + Gamma[k] w[k] (compiled; no Python loop over samples).

    Args:
        d: Phi (N, T or 1, nx, nx) and Gamma (N, T or 1, nx, m); a length-1 time axis means constant.
        w: input coefficients (N, T, m).
        x0: initial states (N, nx).

    Returns:
        states at every sample, (N, T + 1, nx).
    """
    return propagate_states(
        np.ascontiguousarray(d.Phi), np.ascontiguousarray(d.Gamma), np.ascontiguousarray(w), np.ascontiguousarray(x0, dtype=float)
    )


@dataclass(frozen=True)
class ModelMatrices:
    """Per-interval discretization and per-sample output maps along a parameter trajectory."""

    step: Discretization  # Phi, Gamma: (N, T or 1, ...)
    Cy: np.ndarray  # (N, T + 1 or 1, 2 n_bonds, nx)
    Dy: np.ndarray  # (N, T + 1 or 1, 2 n_bonds, nu)

    def bond_values(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Efforts and flows of every bond, (N, T + 1, 2 n_bonds), from states (N, T + 1, nx) and inputs (N, T + 1, nu)."""
        return (self.Cy @ x[..., None])[..., 0] + (self.Dy @ u[..., None])[..., 0]


def _evaluate(model: StateSpaceModel, theta: np.ndarray, h: float) -> tuple[np.ndarray, ...]:
    mats = model.matrices(theta)
    d = discretize(mats.A, mats.B, h)
    return d.Phi, d.Gamma, mats.Cy, mats.Dy


class _ChebyshevInterpolant:
    """Interpolates every matrix of the model in the one parameter that varies.

    The matrices are analytic in a positive component value, so a Chebyshev interpolant over the
    range the parameter spans reaches round-off with a few nodes; it is accepted only when it
    matches direct evaluation to ``rtol`` at points between the nodes. This replaces one matrix
    exponential per sample by a handful for a whole run.
    """

    def __init__(self, model: StateSpaceModel, base: np.ndarray, index: int, lo: float, hi: float, h: float, degree: int):
        self.index, self.lo, self.hi, self.degree = index, lo, hi, degree
        nodes = chebyshev.chebpts1(degree + 1)
        values = _evaluate(model, self._theta(base, nodes), h)
        self.coefficients = [chebyshev.chebfit(nodes, v.reshape(len(nodes), -1), degree) for v in values]
        self.shapes = [v.shape[1:] for v in values]
        check = chebyshev.chebpts2(degree + 2)
        exact = _evaluate(model, self._theta(base, check), h)
        approx = self._evaluate_at(check, range(len(values)))
        self.error = max(float(np.abs(a - e).max() / (np.abs(e).max() or 1.0)) for a, e in zip(approx, exact))

    def _theta(self, base: np.ndarray, s: np.ndarray) -> np.ndarray:
        theta = np.repeat(base[None, :], len(s), axis=0)
        theta[:, self.index] = self.lo + (s + 1.0) * 0.5 * (self.hi - self.lo)
        return theta

    def _evaluate_at(self, s: np.ndarray, which: range | tuple[int, ...]) -> list[np.ndarray]:
        # a Vandermonde product runs as one BLAS call, far faster than Clenshaw over many samples
        vander = np.ascontiguousarray(chebyshev.chebvander(s, self.degree))
        return [(vander @ self.coefficients[i]).reshape((len(s),) + self.shapes[i]) for i in which]

    def __call__(self, values: np.ndarray, which: tuple[int, ...]) -> list[np.ndarray]:
        """The matrices numbered ``which`` (0 Phi, 1 Gamma, 2 Cy, 3 Dy) at parameter ``values``."""
        return self._evaluate_at(2.0 * (values - self.lo) / (self.hi - self.lo) - 1.0, which)


def matrices_along(
    model: StateSpaceModel, theta_mid: np.ndarray, theta_samples: np.ndarray, h: float, rtol: float = 1e-13
) -> ModelMatrices:
    """Discretization at the interval midpoints and output maps at the samples of one trajectory.

    Args:
        theta_mid: parameters at the middle of each interval, (T, P).
        theta_samples: parameters at each sample, (T + 1, P).
        rtol: accuracy asked of the parameter interpolant, relative to each matrix's largest entry.
    """
    both = np.concatenate([theta_mid, theta_samples])
    columns = np.ascontiguousarray(both.T)  # reductions along rows of a transposed copy are ~30x faster
    varying = np.flatnonzero(columns.max(axis=1) > columns.min(axis=1))
    if len(varying) == 0:
        Phi, Gamma, Cy, Dy = _evaluate(model, both[:1], h)
        return ModelMatrices(Discretization(Phi[None], Gamma[None]), Cy[None], Dy[None])
    if len(varying) == 1:
        j = int(varying[0])
        lo, hi = float(columns[j].min()), float(columns[j].max())
        for degree in (4, 8, 16, 32, 64):
            interpolant = _ChebyshevInterpolant(model, both[0], j, lo, hi, h, degree)
            if interpolant.error <= rtol:
                Phi, Gamma = interpolant(theta_mid[:, j], (0, 1))
                Cy, Dy = interpolant(theta_samples[:, j], (2, 3))
                return ModelMatrices(Discretization(Phi[None], Gamma[None]), Cy[None], Dy[None])
    # several parameters vary at once, or too fast for the interpolant: evaluate each set directly
    Phi, Gamma = _evaluate(model, theta_mid, h)[:2]
    Cy, Dy = _evaluate(model, theta_samples, h)[2:]
    return ModelMatrices(Discretization(Phi[None], Gamma[None]), Cy[None], Dy[None])


def simulate_linear(
    model: StateSpaceModel,
    sample_period: float,
    u: np.ndarray,
    du: np.ndarray,
    theta_mid: np.ndarray,
    theta_samples: np.ndarray,
    x0: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate one system over T intervals.

    Args:
        sample_period: h in s.
        u, du: source values and their time derivatives at the T + 1 samples, (T + 1, nu).
        theta_mid: parameters at the interval midpoints (T, P); theta_samples: at the samples (T + 1, P).
        x0: initial energy variables (nx,).

    Returns:
        states (T + 1, nx) and bond efforts and flows (T + 1, 2 n_bonds).
    """
    with single_threaded_blas():
        mats = matrices_along(model, theta_mid, theta_samples, sample_period)
        w = hermite_coefficients(u, du, sample_period)
        x = propagate(mats.step, w[None], np.asarray(x0, dtype=float)[None])
        return x[0], mats.bond_values(x, u[None])[0]


def unique_rows(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``theta`` (N, P) and, for every row, the index of its copy among them.

    Rows are compared bit for bit, so a row and its representative give the same result in any
    computation. Batches share few parameter sets (every reference row and every healthy plant row
    holds the nominal values), and each distinct set needs one matrix exponential only.
    """
    theta = np.ascontiguousarray(theta, dtype=float)
    n = len(theta)
    if n <= 1:
        return theta, np.zeros(n, dtype=np.intp)
    if n <= FEW_ROWS:  # np.unique's order (its void rows compare as their bytes do), without its sort's overhead
        rows = [row.tobytes() for row in theta]
        order = sorted(set(rows))
        slot = {row: j for j, row in enumerate(order)}
        return theta[[rows.index(row) for row in order]], np.array([slot[row] for row in rows], dtype=np.intp)
    keys = theta.view(np.dtype((np.void, theta.dtype.itemsize * theta.shape[1]))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    return theta[first], inverse.reshape(n)


def simulate_batch(
    model: StateSpaceModel, sample_period: float, u: np.ndarray, du: np.ndarray, theta: np.ndarray, x0: np.ndarray
) -> np.ndarray:
    """Simulate N systems, each with constant parameters, over T intervals.

    Args:
        u, du: source values and derivatives at the samples, (N, T + 1, nu).
        theta: parameters of each system, (N, P).
        x0: initial energy variables, (N, nx).

    Returns:
        states at every sample, (N, T + 1, nx); the same as ``propagate`` of ``hermite_coefficients``
        with each system's own discretization, computed once per distinct parameter set.
    """
    states, _ = simulate_measured(model, sample_period, u, du, theta, x0, np.ones(np.shape(x0)))
    return np.ascontiguousarray(states.transpose(0, 2, 1))


def _checked_inputs(inputs: np.ndarray | None, n: int, input_rows: int) -> np.ndarray:
    """``inputs``, the row of u and du driving each of n systems, as (n,) indices into ``input_rows`` rows; None:
    system i's own row i."""
    rows = np.arange(n) if inputs is None else np.asarray(inputs)
    if rows.shape != (n,) or rows.dtype.kind not in "iu" or (n and not 0 <= rows.min() <= rows.max() < input_rows):
        raise ValueError(f"simulate_batch: inputs must be {n} row indices into the {input_rows} rows of u, got {inputs!r}")
    return np.ascontiguousarray(rows, dtype=np.intp)


def _simulate_rows(
    step: Discretization, index: np.ndarray, u: np.ndarray, du: np.ndarray, inputs: np.ndarray, h: float, x0: np.ndarray,
    gain: np.ndarray, signals: np.ndarray, last: np.ndarray,
) -> None:
    """``simulate_hermite`` over the kernel threads: system s with the discretization of row index[s] of ``step``,
    driven by row inputs[s] of u and du (contiguous arrays)."""
    Phi, Gamma = step.Phi, step.Gamma

    def simulate_part(start: int, stop: int) -> None:
        part = slice(start, stop)
        simulate_hermite(Phi, Gamma, index[part], u, du, inputs[part], h, x0[part], gain[part], signals[part], last[part])

    over_rows(simulate_part, len(index))


def simulate_measured(
    model: StateSpaceModel,
    sample_period: float,
    u: np.ndarray,
    du: np.ndarray,
    theta: np.ndarray,
    x0: np.ndarray,
    gain: np.ndarray,
    out: np.ndarray | None = None,
    inputs: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``simulate_batch`` measured through diagonal measurement matrices, in the sensors' layout.

    Args:
        u, du, theta, x0: as for ``simulate_batch``; u and du may hold fewer rows than the systems where ``inputs`` says
            which row drives each system.
        gain: each system's measurement gain per state, (N, nx) (``ea_gym.sensors.Sensors.gain``).
        out: where to write the signals, (N, nx, T + 1); None: a new array.
        inputs: the row of u and du that drives each system, (N,) integers; None: system i's own row i.

    Returns:
        the signals gain x at every sample, (N, nx, T + 1), equal to the states of ``simulate_batch``
        transposed and multiplied by the gains; and the states at the last sample, (N, nx).
    """
    u, du, x0 = np.asarray(u, dtype=float), np.asarray(du, dtype=float), np.asarray(x0, dtype=float)
    n, nx = len(theta), model.n_states
    if u.ndim != 3 or du.shape != u.shape or (inputs is None and len(u) != n) or u.shape[2] != model.n_inputs or x0.shape != (n, nx):
        raise ValueError(
            f"simulate_batch: u and du must be (N, T + 1, {model.n_inputs}) and x0 (N, {nx}) for N = {n} parameter rows; "
            f"got u {u.shape}, du {du.shape}, x0 {x0.shape}"
        )
    drive = _checked_inputs(inputs, n, len(u))
    signals = np.empty((n, nx, u.shape[1])) if out is None else out
    last = np.empty((n, nx))
    with single_threaded_blas():
        distinct, index = unique_rows(theta)
        step = Discretization(*_evaluate(model, distinct, sample_period)[:2])
    u, du, x0, gain = np.ascontiguousarray(u), np.ascontiguousarray(du), np.ascontiguousarray(x0), np.ascontiguousarray(gain, dtype=float)
    _simulate_rows(step, index, u, du, drive, float(sample_period), x0, gain, signals, last)
    return signals, last


class RowDiscretizations:
    """The discretization of every parameter row of a batch, kept from one simulation to the next: a row the same
    (bit for bit) as the one in its place last time keeps its discretization, the others are computed, once per
    distinct row among them.

    Each row's discretization is arithmetic of its own (numpy's solve, the products and the exponential go
    matrix by matrix), so a kept one is the one the batch would compute again.
    """

    def __init__(self) -> None:
        self._key: tuple[StateSpaceModel, float] | None = None
        self._rows = np.empty((0, 0))  # the parameter rows last given
        self._step = Discretization(Phi=np.empty((0, 0, 0)), Gamma=np.empty((0, 0, 0)))  # of every row

    def update(self, model: StateSpaceModel, sample_period: float, theta: np.ndarray) -> Discretization:
        """The discretization of every row of ``theta`` (N, P): Phi (N, nx, nx) and Gamma (N, nx, HOLD_ORDER nu)."""
        if self._key != (model, sample_period) or self._rows.shape != theta.shape:
            n, nx = len(theta), model.n_states
            self._key, self._rows = None, np.empty(theta.shape)  # valid once every row is computed
            self._step = Discretization(Phi=np.empty((n, nx, nx)), Gamma=np.empty((n, nx, HOLD_ORDER * model.n_inputs)))
            changed = np.arange(n)
        else:
            changed = changed_rows(theta, self._rows)
        if len(changed):
            fresh = theta[changed]
            distinct, index = unique_rows(fresh)
            with single_threaded_blas():
                Phi, Gamma = _evaluate(model, distinct, sample_period)[:2]
            replace_rows(changed, index, fresh, Phi, Gamma, self._rows, self._step.Phi, self._step.Gamma)
            self._key = (model, sample_period)
        return self._step


class MeasuredSimulation:
    """``simulate_measured`` of one batch, window after window (an environment's plants and references): the batch's
    layout checked once, here, and every row's discretization kept while its parameters stay (``RowDiscretizations``).

    Args:
        model: the linear model.
        sample_period: h in s.
        inputs: the row of u and du that drives each of the N systems, (N,) integers.
        input_rows: how many rows u and du hold.
    """

    def __init__(self, model: StateSpaceModel, sample_period: float, inputs: np.ndarray, input_rows: int):
        self.model, self.h = model, float(sample_period)
        self.inputs = _checked_inputs(inputs, len(inputs), input_rows)
        self.discretizations = RowDiscretizations()
        self._own_rows = np.arange(len(self.inputs))  # each system's own row of the kept discretizations

    def __call__(self, u: np.ndarray, du: np.ndarray, theta: np.ndarray, x0: np.ndarray, gain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``simulate_measured``'s signals (N, nx, T + 1) and last states (N, nx), of u and du (input_rows, T + 1, nu),
        theta (N, P), x0 and gain (N, nx), float arrays laid out as declared (not checked again)."""
        n, nx = len(self.inputs), self.model.n_states
        signals, last = np.empty((n, nx, u.shape[1])), np.empty((n, nx))
        step = self.discretizations.update(self.model, self.h, theta)
        u, du, x0, gain = np.ascontiguousarray(u), np.ascontiguousarray(du), np.ascontiguousarray(x0), np.ascontiguousarray(gain)
        _simulate_rows(step, self._own_rows, u, du, self.inputs, self.h, x0, gain, signals, last)
        return signals, last
