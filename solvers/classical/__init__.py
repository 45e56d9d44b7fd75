"""The classical adapters: ODE integrators of the swing equation and the POD surrogate fitted to one.

`common` the machinery they share (the step rule, search boxes, batching over P1, least-squares
identification), `fault_phases` a fault case for the Python-driven integrators; one module an
adapter (`scipy_rk45`, `scipy_odeint`, `casadi_cvodes`, `diffrax_ode` with `diffrax_faults`,
`numba_rk`, `trapezoid`, `pod_spline`); `snapshots` numba-rk's trajectories and their POD, the
training data of the surrogates (a PINN may import it; nothing here imports a PINN); `kernels` the
compiled numba kernels. Importing the package imports none of them.
"""
