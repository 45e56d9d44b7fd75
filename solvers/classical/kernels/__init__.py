"""The numba kernels of the compiled classical adapters, one packed-system layout for all of them.

`layout` the packed system, its modes and the status codes; `jit` how a kernel variant is compiled
and named for numba's on-disk cache; `rk`, `rk_points`, `rk_faults` numba-rk's; `sparse` the
network's part of P_e kept sparse; `trapezoid`, `trapezoid_sparse`, `trapezoid_faults` the
trapezoid's; `pod` pod-spline's queries.
"""
