"""The Gauss-Newton update of the PINNSim step (`solvers.pinn.simulator`): dense, or matrix-free by
preconditioned CGLS, in JAX (float64).

The step's unknowns are each machine's voltage coefficients c (n, 4): theta1 (rad/s), theta2
(rad/s^2), v1 (p.u./s), v2 (p.u./s^2). The residual at the s collocation points t_j is complex,
r (n, s) = V(t_j) - Z (w e^{j delta(t_j)}) (p.u.), solved in least squares as its real and imaginary
parts (2 s n real equations). Its Jacobian in c is

    J dc = own . dc - Z (g . dc),   own (n, s, 4) = dV_k(t_j) / dc_k,   g (n, s, 4) = j w_k e^{j delta_k(t_j)} d delta_k(t_j) / dc_k,

where `.` contracts each machine's own 4 coefficients (both factors block-diagonal in the machines)
and Z (n, n) is the network's dense impedance: the machines couple only through Z. As a real map of
c onto the stacked [Re; Im] equations, J^T y = Re(conj(own) . y) - Re(conj(g) . (Z^H y)) for a
complex y (n, s).

- "dense": J formed (2 s n, 4 n) and (J^T J) dc = -J^T r solved by LU: O((4 n)^3) flops and
  (2 s n) x (4 n) memory a Newton iteration.
- "matrix-free": J and J^T applied as above (two products with Z or Z^H, 2 s n^2 complex
  multiply-adds, an iteration), the same normal equations solved by CGLS (the conjugate gradient
  on J^T J with the residual kept in the equations' space, which loses less accuracy than forming
  J^T J's products), preconditioned by J^T J's exact 4 x 4 diagonal block of each machine
  (`block_preconditioner`: own and coupling, O(n^2) once a step for Z's column norms). An inexact
  Newton (Eisenstat & Walker's forcing term, fixed): CG stops when the normal residual
  |J^T (r + J dc)| is <= forcing times its value at dc = 0, or <= tol times |J|_F |r + J dc| (the
  fixed point's test, below), or after max_cg iterations, and reports its iterations and that
  residual over the larger of its two bounds (<= 1: met).
"""

from __future__ import annotations

from typing import Any, Literal, get_args

import jax
import jax.numpy as jnp

__all__ = [
    "CG_DTYPES",
    "CG_TOL_FLOAT32",
    "NEWTON",
    "CgDtype",
    "Newton",
    "apply_jacobian",
    "apply_transpose",
    "cgls",
    "column_norms",
    "dense_update",
    "formed_jacobian",
    "gauss_newton_update",
    "preconditioner_blocks",
]

Newton = Literal["dense", "matrix-free"]
NEWTON: tuple[str, ...] = get_args(Newton)
# The precision of the matrix-free Newton's products by Z: complex64 halves their cost (they are
# most of a step's) and floors the normal residual CG can resolve near float32's rounding
# (`CG_TOL_FLOAT32`); the Newton's residual r stays float64.
CgDtype = Literal["float64", "float32"]
CG_DTYPES: dict[str, Any] = {"float64": jnp.complex128, "float32": jnp.complex64}
CG_TOL_FLOAT32 = 1e-5  # the lowest cg_tol with complex64 products (their rounding, summed over n)


def apply_jacobian(own: Any, g: Any, Z: Any, dc: Any) -> Any:
    """J dc (n, s) complex p.u. for coefficients dc (n, 4) real: own . dc - Z (g . dc), the product
    by Z in Z's precision (a complex64 Z: `CG_DTYPES`)."""
    coupled = jnp.einsum("ksa,ka->ks", g, dc)
    return jnp.einsum("ksa,ka->ks", own, dc) - (Z @ coupled.astype(Z.dtype)).astype(coupled.dtype)


def apply_transpose(own: Any, g: Any, Z: Any, y: Any) -> Any:
    """J^T y (n, 4) real of the stacked real equations [Re y; Im y] for y (n, s) complex p.u., the
    product by Z^H in Z's precision."""
    zh_y = jnp.einsum("ik,is->ks", Z, y.conj().astype(Z.dtype)).conj().astype(y.dtype)  # no conjugated copy of Z
    return (jnp.einsum("ksa,ks->ka", own.conj(), y) - jnp.einsum("ksa,ks->ka", g.conj(), zh_y)).real


def column_norms(Z: Any) -> Any:
    """sum_i |Z_ik|^2 (n,) (p.u.^2): the coupling's share of J^T J's diagonal blocks."""
    return jnp.sum(jnp.abs(Z) ** 2, axis=0)


def preconditioner_blocks(own: Any, g: Any, Z: Any, norms: Any) -> Any:
    """Each machine's 4 x 4 diagonal block of J^T J (n, 4, 4): the column block of machine k is
    own_k - Z_kk g_k in its own rows and -Z_ik g_k in row i != k, so the block is
    Re[(own_k - Z_kk g_k)^H (own_k - Z_kk g_k)] + (sum_i |Z_ik|^2 - |Z_kk|^2) Re[g_k^H g_k]."""
    z = jnp.diagonal(Z)
    local = own - z[:, None, None] * g  # (n, s, 4)
    return (jnp.einsum("ksa,ksb->kab", local.conj(), local).real
            + (norms - jnp.abs(z) ** 2)[:, None, None] * jnp.einsum("ksa,ksb->kab", g.conj(), g).real)


def cgls(own: Any, g: Any, Z: Any, r: Any, blocks: Any, tol: float, max_iter: int, forcing: float,
         products: Any = None) -> tuple[Any, Any, Any]:
    """min |r + J dc| over dc (n, 4) by CGLS preconditioned by the inverse of `blocks` (n, 4, 4),
    `preconditioner_blocks`: (dc, iterations, the normal residual over its tolerance). r (n, s)
    complex p.u.; Z (n, n) complex128; products: Z for the iterations' products (None: Z; Z in
    complex64: `CG_DTYPES`), the start's J^T r always with Z.

    A normal residual s = J^T (-r - J dc) meets its tolerance when |s| <= forcing |J^T r| (relative
    to its start: the inexact Newton's forcing term, < 1) or |s| <= tol |J|_F |r + J dc| (LSQR's
    test for an inconsistent system: the angle between the equations' residual and J's range, which
    rounding keeps near 1e-16; the least-squares residual |r| does not vanish). The reported measure
    is |s| over the larger of the two bounds (<= 1: met). Stops when met or after max_iter
    iterations. A Newton iterate whose start already meets the second test gets a zero update:
    that test, not the Newton's newton_tol, sets how near the matrix-free Newton stops to the dense
    one's fixed point (J^T r = 0), hence a tol near rounding (1e-12 by default in the adapter); the
    forcing term only sets how many Newton iterations reach it. Complex64 products resolve a normal
    residual down to about `CG_TOL_FLOAT32` of |J|_F |r + J dc| (the equations' residual does not
    vanish, and their rounding is relative to it), so with them tol must be at least that: the
    Newton then stops where |J^T r| <= tol |J|_F |r|, tested at the start in float64."""
    products = Z if products is None else products
    inverse = jnp.linalg.inv(blocks)
    norm_j = jnp.sqrt(jnp.sum(jnp.trace(blocks, axis1=1, axis2=2)))  # |J|_F: the trace of J^T J

    def precondition(s: Any) -> Any:
        return jnp.einsum("kab,kb->ka", inverse, s)

    def measure(s: Any, res: Any, start: Any) -> Any:
        size = jnp.sqrt(jnp.sum(s * s))
        bound = jnp.maximum(forcing * start, tol * norm_j * jnp.sqrt(jnp.sum(jnp.abs(res) ** 2)))
        # an exact start (r = 0: nothing to solve) converges at once instead of dividing by zero
        return jnp.where(size > 0.0, size / bound, 0.0)

    res = -r  # the equations' residual b - J dc at dc = 0, b = -r
    s = apply_transpose(own, g, Z, res)
    z = precondition(s)
    start = jnp.sqrt(jnp.sum(s * s))

    def body(state: tuple) -> tuple:
        dc, res, p, gamma, i, _ = state
        q = apply_jacobian(own, g, products, p)
        alpha = gamma / jnp.sum(jnp.abs(q) ** 2)
        dc, res = dc + alpha * p, res - alpha * q
        s = apply_transpose(own, g, products, res)
        z = precondition(s)
        gamma_next = jnp.sum(s * z)
        return dc, res, z + (gamma_next / gamma) * p, gamma_next, i + 1, measure(s, res, start)

    state = (jnp.zeros_like(s), res, z, jnp.sum(s * z), jnp.asarray(0), measure(s, res, start))
    dc, _, _, _, iterations, size = jax.lax.while_loop(lambda st: (st[4] < max_iter) & (st[5] > 1.0), body, state)
    return dc, iterations, size


def formed_jacobian(own: Any, g: Any, Z: Any) -> Any:
    """J (2 s n, 4 n) real: rows the stacked [Re; Im] equations (machine, point), columns (machine,
    coefficient)."""
    n, s, _ = own.shape
    coupling = Z[:, None, :, None] * jnp.transpose(g, (1, 0, 2))[None]  # (n, s, n, 4): row (i, j), column (k, a)
    full = (own[:, :, None, :] * jnp.eye(n)[:, None, :, None] - coupling).reshape(n * s, n * 4)
    return jnp.concatenate([full.real, full.imag])


def dense_update(own: Any, g: Any, Z: Any, r: Any) -> Any:
    """The Gauss-Newton update (n, 4) with J formed: (J^T J) dc = -J^T r."""
    J = formed_jacobian(own, g, Z)
    rhs = -(J.T @ jnp.concatenate([r.real.ravel(), r.imag.ravel()]))
    return jnp.linalg.solve(J.T @ J, rhs).reshape(r.shape[0], 4)


def gauss_newton_update(newton: Newton, own: Any, g: Any, Z: Any, norms: Any, r: Any, cg_tol: float,
                        max_cg: int, cg_forcing: float, products: Any) -> tuple[Any, Any, Any]:
    """(update (n, 4), CG iterations, CG normal residual over its tolerance (`cgls`)) of one
    Gauss-Newton iteration; the dense path reports 0 and 0.0. own, g (n, s, 4), Z (n, n), norms (n,)
    = `column_norms(Z)`, r (n, s) complex p.u., products: Z for CG's products (Z, or Z in complex64:
    `CG_DTYPES`)."""
    if newton == "dense":
        return dense_update(own, g, Z, r), jnp.asarray(0), jnp.asarray(0.0)
    if newton == "matrix-free":
        return cgls(own, g, Z, r, preconditioner_blocks(own, g, Z, norms), cg_tol, max_cg, cg_forcing, products)
    raise ValueError(f"newton must be one of {NEWTON}, not {newton!r}")
