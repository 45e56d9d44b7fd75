"""diffrax's explicit Runge-Kutta solvers under jax.jit (CPU, float64), all P1 in one compiled call."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any, ClassVar, Literal

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from systems.cases import Observations
from systems.model import SwingSystem, accelerations, smib_system
from solvers.base import AbstractSolver, Estimate, FitReport, SolveError
from solvers.classical import (
    TOLERANCE_CONFIGS,
    ObservationLayout,
    ToleranceOptions,
    identify_least_squares,
)
from solvers.options import PositiveFloat, PositiveInt
from solvers.pinn.jax_pinn import configure_threads

__all__ = ["DiffraxODE"]

METHODS = {"tsit5": diffrax.Tsit5, "dopri5": diffrax.Dopri5, "dopri8": diffrax.Dopri8}
# Sizes of t and P1 compiled as they are (the latency suite's queries); any other size is padded up
# to the next of these or of the powers of two, so arbitrary queries compile a few shapes, not one each.
EXACT_SIZES = (1, 10, 100, 201, 1000, 10000)
GRID_T = np.linspace(0.0, 20.0, 201)


def bucket(n: int) -> int:
    """The compiled size that holds `n` entries: the smallest of EXACT_SIZES and 2**k that is >= n."""
    return min([s for s in EXACT_SIZES if s >= n] + [1 << max(n - 1, 0).bit_length()])


def _pad(x: np.ndarray, size: int) -> np.ndarray:
    """`x` repeated at its last entry up to `size` (sorted times stay non-decreasing)."""
    return x if x.size == size else np.concatenate([x, np.full(size - x.size, x[-1])])


def _vector_field(system: SwingSystem):
    """f(t, y, (P, m, d)) of the n-machine swing equation; y (2n, ...) = [delta_1..n, omega_1..n]
    (rad, rad/s), P (n, ...) p.u., m and d (n,): the matrix form of `systems.model.accelerations`."""
    n = system.n

    def field(t, y, args):
        P, m, d = args
        acc = accelerations(system, list(y[:n]), list(y[n:]), list(P), sin=jnp.sin, m=list(m), d=list(d))
        return jnp.concatenate([y[n:], jnp.stack(acc)])

    return field


@functools.lru_cache(maxsize=16)
def _compiled(system: SwingSystem, method: str, batch: str, adaptive: bool, max_steps: int):
    """Jitted (values, sensitivities) for one system and solver. Tolerances and step are arguments,
    not constants, so a tolerance sweep (or another config) reuses the compiled code.

    values(m (n,), d (n,), rtol, atol, dt, t (n_t,) sorted, P1 (n_p,)) -> (y (2n, n_p, n_t), ok (n_p,));
    sensitivities(m, d, ...) for scalar m, d (every machine's) -> (y, ok, dy/d(m, d) (2n, n_p, n_t, 2)).
    """
    n = system.n
    term = diffrax.ODETerm(_vector_field(system))
    solver = METHODS[method]()
    y0_one = np.array(system.delta0 + system.omega0)

    def solve(m, d, rtol, atol, dt, t, P):  # P (n, ...): one trajectory, or (n, n_p) stacked
        y0 = jnp.broadcast_to(y0_one.reshape((2 * n,) + (1,) * (P.ndim - 1)), (2 * n,) + P.shape[1:])
        control = diffrax.PIDController(rtol=rtol, atol=atol) if adaptive else diffrax.ConstantStepSize()
        sol = diffrax.diffeqsolve(
            term, solver, 0.0, t[-1], None if adaptive else dt, y0, args=(P, m, d),
            saveat=diffrax.SaveAt(ts=t), stepsize_controller=control, max_steps=max_steps,
            adjoint=diffrax.ForwardMode(), throw=False,
        )
        return sol.ys, sol.result == diffrax.RESULTS.successful  # ys (n_t, 2n, ...)

    def values(m, d, rtol, atol, dt, t, P1):
        powers = jnp.broadcast_to(P1, (n, P1.size))  # every machine's mechanical power is P1
        if batch == "stacked":
            ys, ok = solve(m, d, rtol, atol, dt, t, powers)
            y = jnp.moveaxis(ys, 0, -1)
        else:
            ys, ok = jax.vmap(lambda p: solve(m, d, rtol, atol, dt, t, p), in_axes=1)(powers)
            y = jnp.moveaxis(ys, 2, 0)
        ok = ok & jnp.all(jnp.isfinite(y), axis=(0, 2))
        return y, ok

    def of_md(md, rtol, atol, dt, t, P1):
        y, ok = values(jnp.full(n, md[0]), jnp.full(n, md[1]), rtol, atol, dt, t, P1)
        return y, (y, ok)

    def sensitivities(m, d, rtol, atol, dt, t, P1):
        jac, (y, ok) = jax.jacfwd(of_md, has_aux=True)(jnp.stack([m, d]), rtol, atol, dt, t, P1)
        return y, ok & jnp.all(jnp.isfinite(jac), axis=(0, 2, 3)), jac

    return jax.jit(values), jax.jit(sensitivities)


Method = Literal[tuple(METHODS)]  # one of the keys of METHODS


class DiffraxOptions(ToleranceOptions):
    method: Method = "dopri8"
    dt: PositiveFloat | None = None  # s; None: adaptive
    batch: Literal["stacked", "vmap"] = "stacked"
    max_steps: PositiveInt = 16384
    threads: PositiveInt = 2


class DiffraxODE(AbstractSolver):
    """diffrax Tsit5 / Dopri5 / Dopri8 with PID step-size control (or a constant step), jitted, float64.

    Options: method ("dopri8", "dopri5", "tsit5"); rtol, atol (defaults 1e-3, 1e-6: ode45's; PID
    control on the RMS norm of the whole state); dt (None: adaptive; a step in s: constant step,
    rtol and atol unused); batch: "stacked" (the default: one system of 2 * len(P1) states, one step
    size for all) or "vmap" (jax.vmap of one-trajectory solves, each with its own steps; the batched
    while loop runs until the slowest finishes and masks the others); max_steps (a solve that
    needs more fails with SolveError); m_bounds, d_bounds (p.u.), the search box of `identify`;
    threads: XLA's CPU threads (process-wide, applied if XLA has not started yet).

    Measured on 2 cores, 100 x 201 grid, Dopri8, jitted: stacked 0.92 ms at rtol 1e-6 (rel. L2
    3.3e-7), vmap 3.2 ms (4.5e-7); vmap is 3-4x slower at every tolerance and method tried, as
    the few steps (~20) are cheap next to the batched loop's masking and per-trajectory saving.
    Dopri8 is the default method: at rtol 1e-6 it equals Dopri5 and Tsit5 in time (~0.9 ms, most
    of which is diffrax's per-step and per-saved-time loop overhead), and it needs 4-5x fewer steps
    at the tight tolerances identification uses.

    Output times: SaveAt(ts=sorted unique t); t and P1 are padded (repeating the last value) to
    the compiled sizes of `bucket` (the latency suite's sizes exactly, else the next power of two),
    and `fit` compiles the benchmark's shapes (201 times x 1, 10, 100, 1000, 10000 P1; one time x
    one P1). The tolerances and dt are traced arguments: every config shares the compiled code.
    `identify` differentiates through the solver (jax.jacfwd, diffrax.ForwardMode()) for the
    Jacobian of the least squares, compiled once per padded observation layout.
    """

    name: ClassVar[str] = "diffrax"
    compiled: ClassVar[bool] = True
    SCHEMA = DiffraxOptions
    CONFIGS = TOLERANCE_CONFIGS
    FIT_SHAPES: ClassVar[tuple[tuple[int, int], ...]] = (
        (201, 100), (201, 1), (201, 10), (201, 1000), (201, 10000), (1, 1),
    )

    def precision_sweep(self, rtols: Sequence[float]) -> list[dict[str, Any]]:
        """A constant step sweeps dt; an adaptive one the tolerances (the base class's sweep)."""
        if self.options["dt"] is not None:
            # Dopri8 reaches the reference's 1e-12 at dt = 0.2 s already: the curve starts coarse
            return [{"dt": h} for h in (1.0, 0.5, 0.2, 0.1, 0.05, 0.02)]
        return super().precision_sweep(rtols)

    def _functions(self, system: SwingSystem):
        o = self.options
        return _compiled(system, o["method"], o["batch"], o["dt"] is None, int(o["max_steps"]))

    def _controls(self) -> tuple[float, float, float]:
        o = self.options
        return float(o["rtol"]), float(o["atol"]), float(o["dt"] or 0.0)

    def _fit(self) -> FitReport:
        note = configure_threads(self.options["threads"])
        self.system = smib_system(self.case)
        self._values, _ = self._functions(self.system)
        with jax.enable_x64(True):  # device arrays once: converting them cost ~20 us of every query
            self._fixed = tuple(jnp.asarray(x, jnp.float64) for x in (
                self.system.m, self.system.d, *self._controls()))
        p1 = 0.5 * (self.case.p1_min + self.case.p1_max)
        with jax.enable_x64(True):
            for n_t, n_p in self.FIT_SHAPES:  # compile and run once; a failure shows in solve
                t = GRID_T[:n_t] if n_t > 1 else GRID_T[-1:]
                self._values(*self._fixed, t, np.full(n_p, p1))[0].block_until_ready()
        return FitReport(seconds=0.0, message=note)

    def _run(self, times: np.ndarray, P1: np.ndarray) -> np.ndarray:
        """States (2n, len(P1), len(times)) at sorted unique `times`; SolveError naming a failed P1."""
        n_t, n_p = times.size, P1.size
        with jax.enable_x64(True):
            y, ok = self._values(*self._fixed, _pad(times, bucket(n_t)), _pad(P1, bucket(n_p)))
        ok = np.asarray(ok)[:n_p]
        if not ok.all():
            self._fail(P1, ok)
        return np.asarray(y)[:, :n_p, :n_t]

    def _fail(self, P1: np.ndarray, ok: np.ndarray) -> None:
        """Raise SolveError naming the first failed P1 (stacked: the first that fails alone)."""
        if self.options["batch"] == "stacked" and P1.size > 1:
            for p1 in P1:
                self._run(GRID_T[-1:], np.array([p1]))  # raises for a P1 that fails on its own
            where = f"one of P1 in [{P1.min():g}, {P1.max():g}] (the stacked solve)"
        else:
            where = f"P1={P1[np.argmin(ok)]:g}"
        raise SolveError(f"{self.name}: integration failed at {where}: max_steps="
                         f"{self.options['max_steps']} reached or the state is not finite")

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if t.size == 1 or np.all(t[1:] > t[:-1]):
            y = self._run(t, P1)
        else:
            times, order = np.unique(t, return_inverse=True)
            y = self._run(times, P1)[:, :, order]
        return y[0], y[self.system.n]

    def _identify(self, obs: Observations) -> Estimate:
        note = configure_threads(self.options["threads"])
        system = smib_system(self.case)
        values, sensitivities = self._functions(system)
        layout = ObservationLayout.of(obs)
        n_p, n_t = layout.P1.size, layout.t.size
        with jax.enable_x64(True):
            t = jnp.asarray(_pad(layout.t, bucket(n_t)))
            p1 = jnp.asarray(_pad(layout.P1, bucket(n_p)))
        controls = self._controls()

        def simulate(m: float, d: float, with_jacobian: bool):
            with jax.enable_x64(True):
                if with_jacobian:
                    y, ok, jac = sensitivities(m, d, *controls, t, p1)
                else:
                    y, ok = values(np.full(system.n, m), np.full(system.n, d), *controls, t, p1)
                    jac = None
            if not np.asarray(ok)[:n_p].all():
                raise SolveError(f"{self.name}: integration failed at m={m:g}, d={d:g}, one of P1 in "
                                 f"[{layout.P1.min():g}, {layout.P1.max():g}]")
            y = np.asarray(y)[:, :n_p, :n_t]
            if jac is None:
                return y[0], y[system.n], None, None
            jac = np.asarray(jac)[:, :n_p, :n_t]
            return y[0], y[system.n], jac[0], jac[system.n]

        est = identify_least_squares(
            simulate, obs, layout, self.options["m_bounds"], self.options["d_bounds"], analytic_jacobian=True,
            rtol=self.options["rtol"],
        )
        return est._replace(message=f"{est.message} {note}".strip())
