"""Exact discretization and simulation of a bond graph's linear model.

Between two samples the input is the cubic Hermite interpolant of its values and time derivatives at
both samples (error O(h^4), and local, so chunked and whole-run simulations agree), and the state is
propagated exactly through the matrix exponential of an augmented system. Parameters (degradation)
are held at their value at the middle of each sample interval, which keeps the error of a drifting
parameter second order in the step; efforts and flows at a sample use the parameters at that sample.

Everything is batched over N systems: arrays carry a leading system axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.polynomial import chebyshev

from ea_gym.bondgraph.equations import StateSpaceModel
from ea_gym.threads import single_threaded_blas

#: Polynomial pieces per sample interval of the input: u(s) = sum_j w_j s^j / j!, j = 0..3.
HOLD_ORDER = 4


@dataclass(frozen=True)
class Discretization:
    """x[k+1] = Phi x[k] + Gamma w[k], where w[k] stacks the input's Taylor coefficients (HOLD_ORDER * nu)."""

    Phi: np.ndarray
    Gamma: np.ndarray


#: Coefficients b_0..b_13 of the [13/13] Pade approximant of exp (Higham 2005, Table 2.2).
_PADE13 = np.array([
    64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0, 129060195264000.0,
    10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0,
])
#: Largest 1-norm for which the [13/13] approximant is exact to double precision (Higham 2005, Table 2.3).
_THETA13 = 5.371920351148152


@numba.njit(cache=True)
def _matmul(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
    """c = a @ b; explicit loops, since a BLAS call costs more than the product for matrices this small."""
    n = a.shape[0]
    c[:] = 0.0
    for i in range(n):
        for k in range(n):
            aik = a[i, k]
            for j in range(n):
                c[i, j] += aik * b[k, j]


@numba.njit(cache=True)
def _solve(a: np.ndarray, b: np.ndarray) -> None:
    """b = a^-1 b by Gaussian elimination with partial pivoting; a is overwritten."""
    n = a.shape[0]
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        if p != k:
            for j in range(n):
                a[k, j], a[p, j] = a[p, j], a[k, j]
                b[k, j], b[p, j] = b[p, j], b[k, j]
        for i in range(k + 1, n):
            f = a[i, k] / a[k, k]
            for j in range(k + 1, n):
                a[i, j] -= f * a[k, j]
            for j in range(n):
                b[i, j] -= f * b[k, j]
    for k in range(n - 1, -1, -1):
        for j in range(n):
            acc = b[k, j]
            for i in range(k + 1, n):
                acc -= a[k, i] * b[i, j]
            b[k, j] = acc / a[k, k]


@numba.njit(cache=True)
def _pade_polynomial(A2: np.ndarray, A4: np.ndarray, A6: np.ndarray, c: np.ndarray, T: np.ndarray, out: np.ndarray) -> None:
    """out = A6 (c6 A6 + c5 A4 + c4 A2) + c3 A6 + c2 A4 + c1 A2 + c0 I: the even or odd half of the
    [13/13] Pade approximant's coefficients (``_PADE13[0::2]`` or ``[1::2]``); T is a workspace."""
    T[:] = c[6] * A6 + c[5] * A4 + c[4] * A2
    _matmul(A6, T, out)
    out += c[3] * A6 + c[2] * A4 + c[1] * A2
    for i in range(out.shape[0]):
        out[i, i] += c[0]


@numba.njit(cache=True)
def _expm(Z: np.ndarray) -> np.ndarray:
    """e^Z for each of the (M, n, n) matrices: scaling and squaring with the [13/13] Pade approximant (Higham 2005)."""
    odd, even = _PADE13[1::2], _PADE13[0::2]
    n = Z.shape[1]
    out = np.empty_like(Z)
    # one workspace for all matrices: allocations would cost more than the arithmetic
    A, A2, A4, A6, T, W, U, V = np.empty((8, n, n))
    for k in range(Z.shape[0]):
        A[:] = Z[k]
        norm = np.abs(A).sum(axis=0).max()
        s = 0
        if norm > _THETA13:
            s = int(np.ceil(np.log2(norm / _THETA13)))
            A *= 0.5**s
        _matmul(A, A, A2)
        _matmul(A2, A2, A4)
        _matmul(A4, A2, A6)
        # U = A [A6 (b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I]
        _pade_polynomial(A2, A4, A6, odd, T, W)
        _matmul(A, W, U)
        # V = A6 (b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I
        _pade_polynomial(A2, A4, A6, even, T, V)
        # r = (V - U)^-1 (V + U), then squared s times
        T[:] = V - U
        W[:] = V + U
        _solve(T, W)
        for _ in range(s):
            _matmul(W, W, T)
            W[:] = T
        out[k] = W
    return out


def expm(Z: np.ndarray) -> np.ndarray:
    """e^Z over the last two axes of Z (any leading batch shape), accurate to round-off.

    Equal to ``scipy.linalg.expm`` to ~1e-16 relative at the 1-norms of a discretization step (~1);
    scipy loops over a batch in Python, matrix by matrix, which this compiled loop avoids.
    """
    flat = np.ascontiguousarray(Z, dtype=float).reshape((-1,) + Z.shape[-2:])
    return _expm(flat).reshape(Z.shape)


def discretize(A: np.ndarray, B: np.ndarray, h: float) -> Discretization:
    """Exact discretization of dx/dt = A x + B u for a cubic input over one step of ``h`` seconds.

    The augmented state [x, u, u', u'', u'''] has a nilpotent input chain, so the top block row of its
    matrix exponential holds Phi = e^{Ah} and Gamma_j = int_0^h e^{A(h-s)} B s^j / j! ds.
    """
    nx, nu = A.shape[-1], B.shape[-1]
    batch = A.shape[:-2]
    size = nx + HOLD_ORDER * nu
    Z = np.zeros(batch + (size, size))
    Z[..., :nx, :nx] = A
    Z[..., :nx, nx : nx + nu] = B
    for j in range(HOLD_ORDER - 1):
        rows = slice(nx + j * nu, nx + (j + 1) * nu)
        cols = slice(nx + (j + 1) * nu, nx + (j + 2) * nu)
        Z[..., rows, cols] = np.eye(nu)
    E = expm(Z * h)
    return Discretization(Phi=E[..., :nx, :nx], Gamma=E[..., :nx, nx:])


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


@numba.njit(cache=True)
def _propagate(Phi: np.ndarray, Gamma: np.ndarray, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
    n_sys, n_steps, nx = w.shape[0], w.shape[1], x0.shape[1]
    m = w.shape[2]
    x = np.empty((n_sys, n_steps + 1, nx))
    for s in range(n_sys):
        x[s, 0] = x0[s]
        for k in range(n_steps):
            kp = k if Phi.shape[1] > 1 else 0
            for i in range(nx):
                acc = 0.0
                for j in range(nx):
                    acc += Phi[s, kp, i, j] * x[s, k, j]
                for j in range(m):
                    acc += Gamma[s, kp, i, j] * w[s, k, j]
                x[s, k + 1, i] = acc
    return x


def propagate(d: Discretization, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """Run the recursion x[k+1] = Phi[k] x[k] + Gamma[k] w[k] (compiled; no Python loop over samples).

    Args:
        d: Phi (N, T or 1, nx, nx) and Gamma (N, T or 1, nx, m); a length-1 time axis means constant.
        w: input coefficients (N, T, m).
        x0: initial states (N, nx).

    Returns:
        states at every sample, (N, T + 1, nx).
    """
    return _propagate(
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


SYSTEMS_BLOCK = 128  # systems propagated side by side; their lanes are the SIMD axis of the recursion
SAMPLES_CHUNK = 16  # samples of a block's lane-major copies


@numba.njit(cache=True)
def _simulate_hermite(
    Phi: np.ndarray, Gamma: np.ndarray, index: np.ndarray, u: np.ndarray, du: np.ndarray, h: float, x0: np.ndarray,
    gain: np.ndarray, signals: np.ndarray, last: np.ndarray,
) -> None:
    """``propagate`` with constant matrices Phi[index[s]], Gamma[index[s]] for system s and the Hermite
    coefficients of ``hermite_coefficients`` computed on the fly, in the same arithmetic (same result).
    Writes gain[s, i] x_i of system s at every sample to signals (N, nx, T) and its states at the
    last sample to last (N, nx).

    One system's recursion is a chain of dependent sums; ``SYSTEMS_BLOCK`` systems run side by side
    with the system innermost, so the chains of different systems fill the SIMD lanes. Every system
    takes the same operations in the same order as alone, so its result does not depend on the batch.
    """
    n_sys, n_samples, nu = u.shape
    nx = Phi.shape[1]
    m = Gamma.shape[2]
    h2 = h * h
    B = min(SYSTEMS_BLOCK, n_sys)
    # lane-major copies, system last, of SAMPLES_CHUNK samples at a time: they stay in the first-level
    # cache, and so do the lines of the system-major arrays that the copies' loops (lanes innermost,
    # twice as fast as samples innermost) stride across
    P = np.empty((nx, nx, B))
    G = np.empty((nx, m, B))
    load = np.empty((SAMPLES_CHUNK + 1, 2, nu, B))
    w = np.empty((m, B))
    X = np.empty((SAMPLES_CHUNK + 1, nx, B))
    for s0 in range(0, n_sys, B):
        lanes = min(B, n_sys - s0)
        for b in range(lanes):
            for i in range(nx):
                X[0, i, b] = x0[s0 + b, i]
                signals[s0 + b, i, 0] = x0[s0 + b, i] * gain[s0 + b, i]
                for j in range(nx):
                    P[i, j, b] = Phi[index[s0 + b], i, j]
                for j in range(m):
                    G[i, j, b] = Gamma[index[s0 + b], i, j]
        for k0 in range(0, n_samples - 1, SAMPLES_CHUNK):
            steps = min(SAMPLES_CHUNK, n_samples - 1 - k0)
            for k in range(steps + 1):
                for c in range(nu):
                    for b in range(lanes):
                        load[k, 0, c, b] = u[s0 + b, k0 + k, c]
                        load[k, 1, c, b] = du[s0 + b, k0 + k, c]
            for k in range(steps):
                for c in range(nu):
                    for b in range(lanes):
                        u0, u1, d0, d1 = load[k, 0, c, b], load[k + 1, 0, c, b], load[k, 1, c, b], load[k + 1, 1, c, b]
                        slope = (u1 - u0) / h
                        c2 = (3.0 * slope - 2.0 * d0 - d1) / h
                        c3 = (d0 + d1 - 2.0 * slope) / h2
                        w[c, b] = u0
                        w[nu + c, b] = d0
                        w[2 * nu + c, b] = 2.0 * c2
                        w[3 * nu + c, b] = 6.0 * c3
                for i in range(nx):
                    acc = X[k + 1, i]
                    acc[:lanes] = 0.0
                    for j in range(nx):
                        for b in range(lanes):
                            acc[b] += P[i, j, b] * X[k, j, b]
                    for j in range(m):
                        for b in range(lanes):
                            acc[b] += G[i, j, b] * w[j, b]
            for k in range(1, steps + 1):
                for i in range(nx):
                    for b in range(lanes):
                        signals[s0 + b, i, k0 + k] = X[k, i, b] * gain[s0 + b, i]
            X[0] = X[steps]
        for i in range(nx):
            for b in range(lanes):
                last[s0 + b, i] = X[0, i, b]


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


def simulate_measured(
    model: StateSpaceModel,
    sample_period: float,
    u: np.ndarray,
    du: np.ndarray,
    theta: np.ndarray,
    x0: np.ndarray,
    gain: np.ndarray,
    out: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``simulate_batch`` measured through diagonal measurement matrices, in the sensors' layout.

    Args:
        u, du, theta, x0: as for ``simulate_batch``.
        gain: each system's measurement gain per state, (N, nx) (``Monitor.measurement_gain``).
        out: where to write the signals, (N, nx, T + 1); None: a new array.

    Returns:
        the signals gain x at every sample, (N, nx, T + 1), equal to the states of ``simulate_batch``
        transposed and multiplied by the gains; and the states at the last sample, (N, nx).
    """
    u, du, x0 = np.asarray(u, dtype=float), np.asarray(du, dtype=float), np.asarray(x0, dtype=float)
    n, nx = len(theta), model.n_states
    if u.ndim != 3 or du.shape != u.shape or u.shape[0] != n or u.shape[2] != model.n_inputs or x0.shape != (n, nx):
        raise ValueError(
            f"simulate_batch: u and du must be (N, T + 1, {model.n_inputs}) and x0 (N, {nx}) for N = {n} parameter rows; "
            f"got u {u.shape}, du {du.shape}, x0 {x0.shape}"
        )
    signals = np.empty((n, nx, u.shape[1])) if out is None else out
    last = np.empty((n, nx))
    with single_threaded_blas():
        distinct, index = unique_rows(theta)
        mats = model.matrices(distinct)
        step = discretize(mats.A, mats.B, sample_period)
        _simulate_hermite(
            np.ascontiguousarray(step.Phi), np.ascontiguousarray(step.Gamma), index, np.ascontiguousarray(u),
            np.ascontiguousarray(du), float(sample_period), np.ascontiguousarray(x0), np.ascontiguousarray(gain, dtype=float), signals, last,
        )
    return signals, last
