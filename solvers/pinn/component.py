"""The component PINN of `pinnsim`: one classical machine behind its transient reactance against a
bus voltage given, over a short time, as a quadratic polynomial of its angle and magnitude.

Machine k (system base) obeys m delta'' + d delta' = P_m - (E V(t) / x'd) sin(delta - theta(t)).
Divided by beta = E / x'd (p.u.) it takes three numbers, mu = m / beta (s^2/rad), kappa = d / beta
(s/rad) and p = P_m / beta: one network then serves every machine of every case. Two exact
invariances take two more inputs out: the angles only enter as delta - theta, and with
theta(t) = theta0 + theta1 t + theta2 t^2 the relative angle phi = delta - theta0 - theta1 t obeys

    mu phi'' + kappa phi' = p - kappa theta1 - V(t) sin(phi - theta2 t^2),   V(t) = v0 + v1 t + v2 t^2,

from phi(0) = delta0 - theta0, phi'(0) = omega0 - theta1 (the slip): the absolute speed and
theta1 enter only through the slip and the effective power p - kappa theta1. The inputs are then
`INPUTS` (phi0 over the full circle, through its cosine and sine; the rest normalised to [-1, 1]
over the `Domain` box) and t in [0, h]. The output is in residual form, exact at t = 0 in angle,
speed and acceleration (a0 from the equation):

    phi(t) = phi0 + s t + a0 t^2 / 2 + (t^3 / mu) NN(t, t / sqrt(mu), inputs),

so that delta(t) = delta0 + (theta(t) - theta0) + t (...) and omega = phi' + theta1 (forward-mode
derivative of the same network). NN has one of two forms (`Form`). "plain": one output.
"rest-exact": NN = sum_i f_i NN_i, five outputs weighted by the five terms whose vanishing makes
phi(t) = phi0 an exact solution (`forcings`: the power imbalance mu a0, the slip, theta2, v1, v2),
so that a machine at rest against a constant voltage stays exactly at rest. The exact remainder
vanishes wherever all five do and is smooth, so it is such a sum (Hadamard's lemma): the form
restricts nothing else. Training (`train`): Levenberg-Marquardt on solver data (the exact response,
angle and speed, by RK4 at 400 steps a network interval, `exact_response`) and the equation's
residual at collocation points, in float64; the data's generation counts in the fit's seconds.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import jax
import jax.numpy as jnp
import numpy as np

from solvers.atomic import write_atomically
from solvers.pinn.architecture import glorot_weights, layer_shapes, split_flat
from solvers.pinn.optim import OptimResult, levenberg_marquardt

__all__ = ["FORMS", "INPUTS", "Component", "Domain", "Form", "exact_response", "forcings", "outputs", "phi_rate", "train"]

# The columns of a component input x (9,): relative angle (rad), slip (rad/s), theta2 (rad/s^2),
# v0 (p.u.), v1 (p.u./s), v2 (p.u./s^2), mu (s^2/rad), kappa (s/rad), effective power p (p.u.)
INPUTS = ("phi0", "slip", "theta2", "v0", "v1", "v2", "mu", "kappa", "p")
PHI0, SLIP, THETA2, V0, V1, V2, MU, KAPPA, P = range(len(INPUTS))
Form = Literal["plain", "rest-exact"]
FORMS: tuple[str, ...] = get_args(Form)
_RK4_STEPS = 400  # RK4 steps per network interval h of the exact response (error ~1e-11 rad)


@dataclass(frozen=True)
class Domain:
    """The box the network is trained on: t in [0, h] s; phi0 any angle; |slip| <= slip rad/s;
    |theta2| <= theta2 rad/s^2; v0 in v0 p.u.; |v1| <= v1 p.u./s, |v2| <= v2 p.u./s^2; mu, kappa
    and p in their ranges (s^2/rad, s/rad, p.u., the machine on its own beta = E / x'd)."""

    h: float = 0.05
    slip: float = 4.0
    theta2: float = 3.0
    v0: tuple[float, float] = (0.85, 1.15)
    v1: float = 0.6
    v2: float = 0.6
    mu: tuple[float, float] = (0.0025, 0.02)
    kappa: tuple[float, float] = (0.0, 0.012)
    p: tuple[float, float] = (-0.4, 0.6)

    def __post_init__(self) -> None:
        for name in ("v0", "mu", "kappa", "p"):
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) (9,) of the inputs, in `INPUTS` order (phi0: [-pi, pi])."""
        lo = np.array([-np.pi, -self.slip, -self.theta2, self.v0[0], -self.v1, -self.v2, self.mu[0],
                       self.kappa[0], self.p[0]])
        hi = np.array([np.pi, self.slip, self.theta2, self.v0[1], self.v1, self.v2, self.mu[1], self.kappa[1],
                       self.p[1]])
        return lo, hi

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """n inputs (n, 9) uniform in the box."""
        lo, hi = self.bounds()
        return lo + (hi - lo) * rng.uniform(size=(n, lo.size))

    def outside(self, x: np.ndarray) -> np.ndarray:
        """Per input (..., 9) the index of the first column outside the box (phi0 never), -1 if none."""
        lo, hi = self.bounds()
        bad = (x[..., 1:] < lo[1:] - 1e-12) | (x[..., 1:] > hi[1:] + 1e-12)
        return np.where(bad.any(-1), bad.argmax(-1) + 1, -1)


@dataclass(frozen=True)
class Component:
    """A trained component network: its hidden layers (width, depth), domain, output form
    (`Form`) and float64 weights, and how it was trained (`record`: options, seconds, loss, test
    errors)."""

    width: int
    depth: int
    domain: Domain
    theta: np.ndarray = dataclasses.field(compare=False, repr=False)
    record: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)
    form: Form = "plain"

    @property
    def sizes(self) -> tuple[int, ...]:
        return (12,) + (self.width,) * self.depth + (outputs(self.form),)

    def save(self, path: Path) -> None:
        """`path`.npz (the weights) and `path`.json (the rest), each written atomically."""
        info = {"width": self.width, "depth": self.depth, "form": self.form, "domain": dataclasses.asdict(self.domain),
                "record": self.record, "n_params": int(self.theta.size)}
        write_atomically(path.with_name(path.name + ".npz"), lambda f: np.savez(f, theta=self.theta))
        write_atomically(path.with_name(path.name + ".json"), lambda f: f.write(json.dumps(info, indent=1).encode()))

    @classmethod
    def load(cls, path: Path) -> Component:
        """The component saved at `path` (ValueError naming the file if it is not one)."""
        try:
            info = json.loads(path.with_name(path.name + ".json").read_text())
            with np.load(path.with_name(path.name + ".npz")) as data:
                theta = np.asarray(data["theta"], np.float64)
            component = cls(int(info["width"]), int(info["depth"]), Domain(**info["domain"]), theta,
                            dict(info.get("record", {})), info.get("form", "plain"))
        except (OSError, KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path}: not a component PINN ({type(exc).__name__}: {exc})") from exc
        expected = sum(int(np.prod(s)) for s in layer_shapes(component.sizes))
        if theta.size != expected or not np.isfinite(theta).all():
            raise ValueError(f"{path}: {theta.size} weights (finite: {np.isfinite(theta).all()}), {expected} expected")
        return component


def outputs(form: Form) -> int:
    """The network's number of outputs in form `form` (ValueError naming the forms otherwise)."""
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, not {form!r}")
    return 1 if form == "plain" else 5


def forcings(domain: Domain, x: Any) -> Any:
    """(5,) for one input x (9,): the power imbalance mu a0 = p - kappa slip - v0 sin(phi0) (p.u.)
    and the slip, theta2, v1 and v2 over their half-widths in `domain`; all zero exactly where
    phi(t) = phi0 solves the machine's equation (at rest against a constant voltage)."""
    return jnp.stack([x[P] - x[KAPPA] * x[SLIP] - x[V0] * jnp.sin(x[PHI0]), x[SLIP] / domain.slip,
                      x[THETA2] / domain.theta2, x[V1] / domain.v1, x[V2] / domain.v2])


def _network(sizes: tuple[int, ...], domain: Domain, form: Form, theta: Any, x: Any, t: Any) -> Any:
    """phi (rad) at scalar t (s) for one input x (9,), traced in JAX."""
    lo, hi = domain.bounds()
    mid, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    scaled = (x - mid) / half
    tau_max = domain.h / np.sqrt(domain.mu[0])
    features = jnp.concatenate([jnp.stack([2.0 * t / domain.h - 1.0, 2.0 * t / jnp.sqrt(x[MU]) / tau_max - 1.0,
                                           jnp.cos(x[PHI0]), jnp.sin(x[PHI0])]), scaled[1:]])
    params = split_flat(layer_shapes(sizes), theta)[0]
    h = features
    for w, b in zip(params[0:-2:2], params[1:-2:2]):
        h = jnp.tanh(h @ w + b)
    out = h @ params[-2] + params[-1]
    nn = out[0] if form == "plain" else jnp.dot(forcings(domain, x), out)
    a0 = (x[P] - x[KAPPA] * x[SLIP] - x[V0] * jnp.sin(x[PHI0])) / x[MU]
    return x[PHI0] + t * (x[SLIP] + t * (0.5 * a0 + t * nn / x[MU]))


def phi_rate(sizes: tuple[int, ...], domain: Domain, form: Form, theta: Any, x: Any, t: Any) -> tuple[Any, Any]:
    """(phi rad, phi' rad/s) at scalar t for one input x (9,), JAX."""
    return jax.jvp(lambda s: _network(sizes, domain, form, theta, x, s), (t,), (jnp.ones_like(t),))


def _residual(sizes: tuple[int, ...], domain: Domain, form: Form, theta: Any, x: Any, t: Any) -> Any:
    """The equation's residual in acceleration units (rad/s^2) at scalar t."""
    (phi, rate), (_, acc) = jax.jvp(lambda s: phi_rate(sizes, domain, form, theta, x, s), (t,), (jnp.ones_like(t),))
    v = x[V0] + t * (x[V1] + t * x[V2])
    return acc + (x[KAPPA] * rate - x[P] + v * jnp.sin(phi - x[THETA2] * t * t)) / x[MU]


def _rhs(y: np.ndarray, t: float, x: np.ndarray) -> np.ndarray:
    phi, rate = y
    v = x[:, V0] + t * (x[:, V1] + t * x[:, V2])
    return np.array([rate, (x[:, P] - x[:, KAPPA] * rate - v * np.sin(phi - x[:, THETA2] * t * t)) / x[:, MU]])


def exact_response(x: np.ndarray, times: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(phi, phi') (len(times), N) of inputs x (N, 9) at sorted times (s) >= 0: classical RK4 at
    `_RK4_STEPS` steps per `h` seconds (or finer), vectorised over the inputs."""
    y, t, out = np.array([x[:, PHI0], x[:, SLIP]], np.float64), 0.0, []
    for target in np.asarray(times, np.float64):
        count = int(np.ceil((target - t) / h * _RK4_STEPS - 1e-9))
        dt = (target - t) / max(count, 1)
        for _ in range(count):
            k1 = _rhs(y, t, x)
            k2 = _rhs(y + 0.5 * dt * k1, t + 0.5 * dt, x)
            k3 = _rhs(y + 0.5 * dt * k2, t + 0.5 * dt, x)
            k4 = _rhs(y + dt * k3, t + dt, x)
            y, t = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), t + dt
        out.append(y.copy())
    both = np.array(out)
    return both[:, 0], both[:, 1]


@functools.lru_cache(maxsize=4)
def _training_functions(sizes: tuple[int, ...], domain: Domain, form: Form, physics_weight: float,
                        rate_weight: float) -> tuple[Any, Any]:
    def data(theta, x, t):
        phi, rate = phi_rate(sizes, domain, form, theta, x, t)
        return jnp.stack([phi, rate_weight * rate])

    def rows(theta, xu, tu, yu, ru, xf, tf):
        fit = jax.vmap(lambda x, t: data(theta, x, t))(xu, tu) - jnp.stack([yu, rate_weight * ru], -1)
        physics = jax.vmap(lambda x, t: _residual(sizes, domain, form, theta, x, t))(xf, tf)
        return jnp.concatenate([fit.ravel(), physics_weight * physics])

    def jacobian(theta, xu, tu, yu, ru, xf, tf):
        fit = jax.vmap(jax.jacrev(data), (None, 0, 0))(theta, xu, tu)  # (N, 2, P)
        physics = jax.vmap(jax.grad(lambda th, x, t: _residual(sizes, domain, form, th, x, t)), (None, 0, 0))(theta, xf, tf)
        return jnp.concatenate([fit.reshape(-1, theta.size), physics_weight * physics])

    return jax.jit(rows), jax.jit(jacobian)


def train(domain: Domain, *, width: int, depth: int, seed: int, trajectories: int, times: int, n_f: int,
          physics_weight: float, rate_weight: float, max_iterations: int,
          max_seconds: float | None, form: Form = "plain") -> tuple[Component, OptimResult]:
    """A component network trained from `seed`: `trajectories` exact responses sampled in the box,
    each at t = h and `times` - 1 random times of (0, h) (its data rows: phi in rad and, weighted by
    `rate_weight` (s), phi' in rad/s: the speed error is what a chain of intervals propagates), and
    `n_f` collocation points of the residual (rad/s^2, weighted by `physics_weight`, s^2);
    Levenberg-Marquardt for at most `max_iterations` within `max_seconds` (None: no limit), data
    generation included; the output in form `form` (`Form`)."""
    start = time.perf_counter()
    deadline = np.inf if max_seconds is None else start + max_seconds
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xC0A9]))
    xu = domain.sample(trajectories, rng)
    grid = np.linspace(0.0, domain.h, 65)[1:]
    phi_grid, rate_grid = exact_response(xu, grid, domain.h)  # (64, N) each
    pick = np.column_stack([np.full(trajectories, grid.size - 1), rng.integers(0, grid.size - 1, (trajectories, times - 1))])
    rows_of = np.arange(trajectories)[:, None]
    tu, yu, ru = grid[pick].ravel(), phi_grid[pick, rows_of].ravel(), rate_grid[pick, rows_of].ravel()
    xu = np.repeat(xu, times, axis=0)
    xf, tf = domain.sample(n_f, rng), rng.uniform(0.0, domain.h, n_f)
    data_s = time.perf_counter() - start
    sizes = (12,) + (width,) * depth + (outputs(form),)
    theta0 = np.concatenate(glorot_weights(sizes, np.random.default_rng(np.random.SeedSequence([seed, 0x5EED]))))
    rows, jacobian = _training_functions(sizes, domain, form, float(physics_weight), float(rate_weight))
    with jax.enable_x64(True):
        args = tuple(jnp.asarray(a) for a in (xu, tu, yu, ru, xf, tf))

        def r(theta: np.ndarray) -> np.ndarray:
            return np.asarray(rows(jnp.asarray(theta), *args))

        def j(theta: np.ndarray) -> np.ndarray:
            return np.asarray(jacobian(jnp.asarray(theta), *args))

        result = levenberg_marquardt(r, j, theta0, max_iterations=max_iterations, deadline=deadline)
    record = {"seed": seed, "trajectories": trajectories, "times": times, "n_f": n_f, "physics_weight": physics_weight,
              "rate_weight": rate_weight, "iterations": result.iterations, "loss": result.loss,
              "message": result.message, "data_seconds": data_s, "seconds": time.perf_counter() - start}
    return Component(width, depth, domain, result.theta, record, form), result
