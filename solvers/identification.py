"""When an identification of every machine's (m_k, d_k) can be trusted, and how far: the rules every adapter shares.

An adapter's `_identify` returns an `Estimate`: the point estimate and, where it has one, the
Gauss-Newton covariance of (log m, log d) with its residual degrees of freedom. `AbstractSolver.identify`
turns it into standard errors, 95 % intervals and a verdict (`assess`, with `data_shortfall` of the
observations), so the rules below are written once. A failed verdict keeps the estimate: it is
reported, not trusted.

The rules (success=False with the reason in the message when any applies):
- too few distinct samples: fewer than `MIN_DISTINCT_SAMPLES` = 5 distinct (t, P1) pairs. Two
  unknowns need two, and a residual variance needs more; 5 leaves 3 degrees of freedom on delta
  alone, where the Student-t 97.5 % quantile is 3.18 (12.7 at 1, 4.30 at 2): below that the interval
  is the quantile's, not the data's. Few samples of an oscillation also alias: several m (periods)
  fit 3 or 4 points, which no local interval shows. Repeats of one sample add no information on
  (m, d), so they do not count. An observed omega does not lower the count: delta and omega of one
  state pin (m, d) down exactly, with nothing left to measure the misfit by.
- on a bound: the estimate lies within `BOUND_RTOL` = 1e-3 (relative) of a bound of the search box;
  the minimum of the misfit is then at or beyond the box, and the estimate is the box's, not the data's.
- ill-conditioned: cond(J^T J) of the (log m, log d) Jacobian above `MAX_CONDITION` = 1e8, i.e. the
  data constrain one combination of log m and log d 1e4 times less than the other; with noise-free
  data the residual variance is ~0 and the interval cannot show this, the condition number does.
  (Measured, SMIB identification case: 1.6-3 for 100 samples of the grid, 7e2 for 30 samples in
  the first 0.05 s.)
- meaningless interval: a 95 % half-width larger than the estimate itself ((high - low) / 2 > value).
- non-finite estimate or covariance.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from systems.cases import Observations

__all__ = [
    "BOUND_RTOL", "MAX_CONDITION", "MAX_REL_HALF_WIDTH", "MIN_DISTINCT_SAMPLES", "Assessment", "Estimate",
    "assess", "data_shortfall", "gauss_newton_covariance", "linearised_covariance",
]

MIN_DISTINCT_SAMPLES = 5
BOUND_RTOL = 1e-3
MAX_CONDITION = 1e8
MAX_REL_HALF_WIDTH = 1.0
_NAN = float("nan")
_NAN2 = (_NAN, _NAN)


class Estimate(NamedTuple):
    """What an adapter's `_identify` returns: m, d (n,) p.u. (one per machine; a number is one
    machine's), iterations, the method's own success and message; cov_log, the (2n, 2n) covariance
    of (log m_1..n, log d_1..n) (None when unknown), with dof residual degrees of freedom (for the
    Student-t quantile) and condition, cond(J^T J) of the Jacobian it came from; bounds, the search
    boxes (m_box, d_box), each (n, 2) rows (low, high) p.u., None without one."""

    m: np.ndarray
    d: np.ndarray
    iterations: int
    success: bool
    message: str
    cov_log: np.ndarray | None = None
    dof: int = 0
    condition: float = _NAN
    bounds: tuple[np.ndarray, np.ndarray] | None = None


class Assessment(NamedTuple):
    """The verdict on an `Estimate`: success, message, standard errors m_se, d_se (n,) p.u. (delta
    method: value x se of its log) and 95 % intervals m_ci95, d_ci95 (n, 2) rows (low, high) p.u.;
    NaN when unknown."""

    success: bool
    message: str
    m_se: np.ndarray
    d_se: np.ndarray
    m_ci95: np.ndarray
    d_ci95: np.ndarray


def data_shortfall(obs: Observations) -> str | None:
    """Why `obs` cannot support an estimate of (m, d) (too few distinct (t, P1) samples), or None."""
    distinct = np.unique(np.stack([obs.t, obs.P1]), axis=1).shape[1]
    if distinct < MIN_DISTINCT_SAMPLES:
        return (f"too few distinct samples: {distinct} distinct (t, P1) of {len(obs)}, identification "
                f"needs at least {MIN_DISTINCT_SAMPLES} (2 unknowns a machine, one value a machine "
                "each, and a residual variance)")
    return None


def gauss_newton_covariance(J: np.ndarray, r: np.ndarray, model_error: float = 0.0,
                            ) -> tuple[np.ndarray, int, float]:
    """(cov, dof, condition) of the parameters of a least-squares fit from its Jacobian J (n, p) and
    residuals r (n,) at the solution: cov = (s^2 + model_error^2) (J^T J)^-1, s^2 = ||r||^2 / (n - p)
    (one noise variance for all rows, independent errors, the model linear near the solution),
    dof = n - p, condition = cond(J^T J). cov is NaN when dof < 1 or J^T J is singular.

    model_error: the norm (over all n rows) of a systematic error of the model itself, such as a
    simulator's integration error: correlated over the samples, it shifts the estimate by up to
    model_error / sigma_min(J) whatever its direction, which the term model_error^2 (J^T J)^-1
    bounds; without it, noise-free data give an interval of the misfit's size that an estimate
    biased by the integration error misses (measured, scipy-odeint "tight", 100 noise-free samples:
    d off by 4e-11 relative, interval +-1.2e-11)."""
    J, r = np.asarray(J, np.float64), np.asarray(r, np.float64)
    n, p = J.shape
    A = J.T @ J
    condition = float(np.linalg.cond(A)) if np.isfinite(A).all() else math.inf
    dof = n - p
    if dof < 1 or not np.isfinite(condition):
        return np.full((p, p), _NAN), max(dof, 0), condition
    s2 = float(r @ r) / dof + model_error ** 2
    try:
        cov = s2 * np.linalg.inv(A)
    except np.linalg.LinAlgError:
        cov = np.full((p, p), _NAN)
    return cov, dof, condition


def linearised_covariance(J: np.ndarray, r: np.ndarray, n_data: int, k: int, rcond: float = 1e-13,
                          ) -> tuple[np.ndarray, int, float]:
    """(cov, dof, condition) of the last `k` of the P parameters of a least-squares fit whose first
    `n_data` residuals are noisy data and whose others are noise-free constraints (a PINN's swing
    residuals), from the Jacobian J (N, P) and residuals r (N,) at the solution.

    The fitted parameters move with the data's noise e by d theta = -H^+ J_d^T e (the first-order
    response at a minimum, H = J^T J over every residual, H^+ its pseudo-inverse: a direction
    nothing constrains does not move), so cov = s^2 (H^+ J_d^T)(H^+ J_d^T)^T over every parameter,
    network weights included: the weights that trade off against the last k parameters widen
    their interval. With J = U S V^T, H^+ J_d^T = V S^-1 U_d^T (U_d the first n_data rows of U,
    singular values below rcond x the largest dropped).

    s^2, the noise variance, from the leave-one-out residuals r_i / (1 - h_i) (h = diag of the data's
    hat matrix J_d H^+ J_d^T, the row norms of U_d): a network with about as many weights as
    samples nearly interpolates the noise, further than its linearisation says (so even
    ||r_d||^2 / (n - sum h) is too small), which the residual of each sample left out does not
    hide; it adds the fit's own variance at the sample, so the interval errs wide (coverage
    measured by `swingbench run --suite identification --noise-draws 20`, docs/methods.md).
    Samples the fit interpolates exactly (1 - h_i < 1e-8) tell nothing of the noise and are
    left out.
    dof = samples used - k; condition = cond(cov); cov is NaN when dof < 1."""
    J, r = np.asarray(J, np.float64), np.asarray(r, np.float64)
    U, S, Vt = np.linalg.svd(J, full_matrices=False)
    keep = S > rcond * S[0] if S.size and S[0] > 0 else np.zeros(S.shape, bool)
    U_d, S, V_k = U[:n_data, keep], S[keep], Vt[keep][:, -k:]
    left = 1.0 - np.sum(U_d ** 2, axis=1)
    usable = left > 1e-8
    dof = int(usable.sum()) - k
    if dof < 1:
        return np.full((k, k), _NAN), max(dof, 0), math.inf
    s2 = float(np.mean((r[:n_data][usable] / left[usable]) ** 2))
    response = (V_k.T / S) @ U_d.T  # (k, n_data): d theta_last / d data residual
    cov = s2 * (response @ response.T)
    condition = float(np.linalg.cond(cov)) if np.isfinite(cov).all() else math.inf
    return cov, dof, condition


def _t_quantile(dof: int) -> float:
    if dof < 1:
        return _NAN
    from scipy.stats import t  # imported here: scipy.stats costs ~0.2 s to import

    return float(t.ppf(0.975, dof))


def _on_bound(value: float, bounds) -> str | None:
    for side, bound in zip(("lower", "upper"), bounds):
        if abs(math.log(value / bound)) <= BOUND_RTOL:
            return side
    return None


def _label(key: str, k: int, n: int) -> str:
    return key if n == 1 else f"{key}_{k + 1}"


def assess(est: Estimate, shortfall: str | None = None) -> Assessment:
    """Standard errors, 95 % intervals and the verdict of the module's rules for `est`; `shortfall`,
    the data's (`data_shortfall`), fails it too. Every machine's m_k and d_k is judged; a rule
    that fails for one fails the estimate (the message names it, m_2 for machine 2; m alone when
    there is one machine).

    Intervals are exp(log value +- q se_log), q the Student-t 97.5 % quantile at est.dof: the fit is
    in log parameters, so the interval is the Gauss-Newton one there, mapped; positive and
    asymmetric. The standard errors are the delta method's, value x se_log."""
    reasons = [shortfall] if shortfall else []
    values = {"m": np.atleast_1d(np.asarray(est.m, np.float64)), "d": np.atleast_1d(np.asarray(est.d, np.float64))}
    n = values["m"].size
    finite = all(bool(np.all(np.isfinite(v) & (v > 0))) for v in values.values())
    se = {key: np.full(n, _NAN) for key in values}
    ci = {key: np.full((n, 2), _NAN) for key in values}
    if not finite:
        reasons.append(f"non-finite or non-positive estimate m={values['m'].tolist()!r}, d={values['d'].tolist()!r}")
    elif est.cov_log is not None:
        cov = np.asarray(est.cov_log, np.float64)
        q = _t_quantile(est.dof)
        for i, key in enumerate(("m", "d")):
            for k in range(n):
                var = cov[i * n + k, i * n + k]
                if not (np.isfinite(var) and var >= 0):
                    continue
                se_log = math.sqrt(var)
                value = float(values[key][k])
                se[key][k] = value * se_log
                if math.isfinite(q):
                    with np.errstate(over="ignore", under="ignore"):  # a huge se_log gives (0, inf): no interval
                        ci[key][k] = (value * np.exp(-q * se_log), value * np.exp(q * se_log))
    if finite and est.bounds is not None:
        for key, boxes in zip(("m", "d"), est.bounds):
            boxes = np.asarray(boxes, np.float64).reshape(n, 2)
            for k in range(n):
                side = _on_bound(float(values[key][k]), boxes[k])
                if side:
                    reasons.append(f"{_label(key, k, n)}={values[key][k]:.6g} is on the {side} bound of the "
                                   f"search box {tuple(boxes[k].tolist())}: the data's minimum is at or outside it")
    if finite and est.cov_log is not None:
        if not (math.isfinite(est.condition) and est.condition <= MAX_CONDITION):
            reasons.append(f"ill-conditioned: cond(J^T J) = {est.condition:.3g} > {MAX_CONDITION:.0e}")
        for key in ("m", "d"):
            for k in range(n):
                low, high = ci[key][k]
                if not (math.isfinite(low) and math.isfinite(high)):
                    reasons.append(f"no finite 95 % interval for {_label(key, k, n)}")
                elif (high - low) / 2 > MAX_REL_HALF_WIDTH * values[key][k]:
                    reasons.append(f"95 % interval of {_label(key, k, n)} [{low:.3g}, {high:.3g}] is wider "
                                   "than the estimate")
    success = bool(est.success) and not reasons
    message = "; ".join([*reasons, est.message]) if reasons else est.message
    return Assessment(success, message, se["m"], se["d"], ci["m"], ci["d"])
