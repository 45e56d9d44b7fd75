"""The `pinnsim` adapter's options (`PinnSimOptions`), its step limits and sweep, and the config
"faults"' training domain (`FAULT_DOMAIN`): data apart from the adapter (`solvers.pinn.pinnsim`)."""

from __future__ import annotations

from solvers.options import (
    NonNegativeFloat,
    NonNegativeInt,
    OptionSchema,
    PositiveFloat,
    PositiveFloats,
    PositiveInt,
)
from solvers.pinn.component import Domain, Form
from solvers.pinn.simulator_newton import CgDtype, Newton

__all__ = ["FAULT_CONFIG", "FAULT_DOMAIN", "H_MAX", "STEP_SWEEP", "V0_MAX", "PinnSimOptions"]

H_MAX = 0.25  # s: the longest step; the component is tested over a step of this length
# p.u.: the default network's highest terminal voltage, above `Domain`'s 1.15: case9241pegase's
# terminals reach past 1.15 p.u. at its largest P1 (one network for every grid of the suites)
V0_MAX = 1.2
STEP_SWEEP = (0.25, 0.1, 0.05, 0.025, 0.01)  # s: the work-precision sweep of h, coarsest first
# The config "faults": the component's domain widened for a fault case (`Domain`'s fields of the
# options below): a terminal voltage down to 0 p.u. (a machine at or next to the faulted bus), the
# terminal angle of a machine next to the fault accelerating with it (theta2), the larger slips,
# and voltage rates (v1, v2) that hold the post-fault swings of a clearing time just past the CCT
# until they cross the cct suite's criterion on all twelve contingencies (v1 <= 2, v2 <= 3 left
# ieee39-bus29-line28-29's bracket at 14.4 ms: docs/pinnsim.md). Its network has the default's
# rest-exact output form (the plain form's one-step error on the narrower domain was 8x larger in
# the median). Its step is 0.1 s (at 0.25 s wscc9's stable clearing times missed COI rel. L2 1e-2:
# 5.4e-2 against 4.5e-3), and a refused clearing time is simulated again at 0.25 s: the polynomials of
# a shorter step stay inside the domain longer on some contingencies, those of the longer on others.
FAULT_DOMAIN = {"v0_min": 0.0, "v0_max": 1.2, "slip_max": 6.0, "theta2_max": 30.0, "v1_max": 3.0, "v2_max": 6.0}
FAULT_CONFIG = {**FAULT_DOMAIN, "h": 0.1, "retry_h": (0.25,)}


class PinnSimOptions(OptionSchema):
    """h (s): the simulator's step, in (0, H_MAX]; retry_h (s): steps, each in (0, H_MAX], a P1 whose trajectory
    failed at h (a step's Newton or CG, or a machine out of the domain) is simulated again with, in turn, until
    one holds throughout (a step met before is skipped); where none does, the attempt that held longest is the
    answer's part before its failure (`PinnSim._attempts`); collocation: points t_j = h j / s of a step's
    network equation (>= 2); max_newton Gauss-Newton iterations a step, stopping when the largest update is <=
    newton_tol (rad, p.u.); newton: the update's linear solve, "dense" (the normal matrix formed, O((4 n)^3) an
    iteration) or "matrix-free" (CGLS with products by the network's impedance, preconditioned per machine, to a
    normal residual <= cg_forcing (< 1) of its start or <= cg_tol of |J|_F |r| within max_cg iterations: an
    inexact Newton, whose fixed point cg_tol sets; `solvers.pinn.simulator_newton.cgls`). The
    component network: net_h (s) its time range, its domain (`Domain`: |slip| <= slip_max rad/s, |theta2| <=
    theta2_max rad/s^2, v0 in [v0_min, v0_max] p.u., |v1| <= v1_max p.u./s, |v2| <= v2_max p.u./s^2), its
    output's form (`solvers.pinn.component.Form`: "rest-exact" holds a machine at rest exactly), hidden layers x
    width tanh, trained from `seed` on `trajectories` exact responses at `times` times each (angles, and speeds
    weighted by `rate_weight`, s) and `n_f` collocation points of the equation weighted by `physics_weight`
    (s^2: rad/s^2 against rad), for max_iterations Levenberg-Marquardt iterations within max_seconds;
    component_dir: where trained networks are kept (None: train every fit)."""

    h: PositiveFloat = 0.25
    retry_h: PositiveFloats = ()
    collocation: PositiveInt = 4
    max_newton: PositiveInt = 20
    newton_tol: PositiveFloat = 1e-9
    newton: Newton = "dense"
    cg_tol: PositiveFloat = 1e-12
    max_cg: PositiveInt = 200
    cg_forcing: PositiveFloat = 1e-12
    cg_dtype: CgDtype = "float64"
    net_h: PositiveFloat = 0.05
    slip_max: PositiveFloat = Domain.slip
    theta2_max: PositiveFloat = Domain.theta2
    v0_min: NonNegativeFloat = Domain.v0[0]
    v0_max: PositiveFloat = V0_MAX
    v1_max: PositiveFloat = Domain.v1
    v2_max: PositiveFloat = Domain.v2
    form: Form = "rest-exact"
    hidden_layers: PositiveInt = 2
    width: PositiveInt = 24
    trajectories: PositiveInt = 1000
    times: PositiveInt = 6
    n_f: NonNegativeInt = 2000
    physics_weight: PositiveFloat = 1e-3
    rate_weight: PositiveFloat = 0.1
    max_iterations: PositiveInt = 3000
    max_seconds: PositiveFloat | None = 900.0
    seed: NonNegativeInt = 0
    component_dir: str | None = ".cache/models/pinnsim-component"
    threads: PositiveInt = 2
