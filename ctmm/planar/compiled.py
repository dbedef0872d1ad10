"""Compiled fast path: the O(n) acceleration sweep + RK4 time loop in C (gcc, ctypes).

Pure Python spends ~3-6 us per body per sweep (see ``benchmarks/planar_chain.py``); the same
recursion in C costs tens of nanoseconds.  The kernel below is the C transcription of
:func:`ctmm.planar.fast_sweep.riccati_kernel` (explicit case, ``kappa = 0``) and of
:func:`ctmm.planar.sweep.body_terms`, for *revolute* trees with constant hinge-law
coefficients, constant reference angles and torques, gravity and no external loads -- the
fixed-scene case of DESIGN section 9.  The whole time interval runs inside C (one call per
simulation), so the Python overhead is paid once.  The RK4 step in the C loop is not written by
hand: :func:`ctmm.ode.second_order_rk4_c` generates it from the one scheme statement,
:func:`ctmm.ode.rk4_step` (same operations in the same order, so the same rounding).

The library is compiled on first use with ``gcc -O2 -shared -fPIC`` and cached on disk by
:mod:`ctmm.codegen` (folder: :func:`ctmm.codegen.cache_directory`, keyed by the SHA-256 of the C
text, the compiler and the flags).  The notation is the one of :mod:`ctmm.planar.sweep`.
"""
from __future__ import annotations

import ctypes
import time as _time
from functools import lru_cache

import numpy as np

from ..codegen import load_ctypes
from ..errors import ModelError
from ..ode import second_order_rk4_c
from .guards import check_scheme, check_stored, divergence_guard
from .integrate import PlanarSimulation, check_store_every, initial_coordinates, step_total
from .model import REVOLUTE, PlanarModel

C_SOURCE = r"""
#include <math.h>

/* body data (per body j): parent, ex, ey (parent end in parent frame, rel. inboard),
   cx, cy (centre of mass rel. inboard), m, J, k, c, r (rest), u (torque), g0 (ground angle) */
static void accel(int nb, const int *parent, const double *ex, const double *ey,
                  const double *cx, const double *cy, const double *m, const double *J,
                  const double *k, const double *c, const double *r, const double *u,
                  const double *g0, double gx, double gy, const double *th, const double *w,
                  double *out, double *work)
{
    double *P = work, *S = work + 9 * nb, *D = work + 12 * nb, *T = work + 13 * nb;
    double *E = work + 14 * nb, *A = work + 20 * nb, *cs = work + 23 * nb, *sn = work + 24 * nb;
    for (int j = 0; j < nb; j++) { cs[j] = cos(th[j]); sn[j] = sin(th[j]); }
    for (int j = 0; j < nb; j++) {
        double rcx = cs[j] * cx[j] - sn[j] * cy[j], rcy = sn[j] * cx[j] + cs[j] * cy[j];
        double mj = m[j], w2 = w[j] * w[j];
        double *p = P + 9 * j, *s = S + 3 * j, *e = E + 6 * j;
        p[0] = mj; p[1] = 0.0; p[2] = -mj * rcy;
        p[3] = 0.0; p[4] = mj; p[5] = mj * rcx;
        p[6] = -mj * rcy; p[7] = mj * rcx; p[8] = J[j] + mj * (rcx * rcx + rcy * rcy);
        s[0] = -mj * (w2 * rcx + gx);
        s[1] = -mj * (w2 * rcy + gy);
        s[2] = -mj * (rcx * gy - rcy * gx);
        int pa = parent[j];
        double dth, dw;
        if (pa >= 0) {
            double rx = cs[pa] * ex[j] - sn[pa] * ey[j], ry = sn[pa] * ex[j] + cs[pa] * ey[j];
            double wp2 = w[pa] * w[pa];
            e[0] = -ry; e[1] = rx; e[2] = -wp2 * rx; e[3] = -wp2 * ry;
            dth = th[j] - th[pa]; dw = w[j] - w[pa];
        } else {
            e[0] = e[1] = e[2] = e[3] = 0.0;
            dth = th[j] - g0[j]; dw = w[j];
        }
        T[j] = u[j] - k[j] * (dth - r[j]) - c[j] * dw;
    }
    for (int j = nb - 1; j >= 0; j--) {
        double *p = P + 9 * j, *s = S + 3 * j, *e = E + 6 * j;
        double d = p[8];
        D[j] = d;
        double rr = (T[j] - s[2]) / d;
        double f0 = p[2] / d, f1 = p[5] / d, f2 = p[8] / d;
        double q00 = p[0] - f0 * p[6], q01 = p[1] - f0 * p[7], q02 = p[2] - f0 * p[8];
        double q10 = p[3] - f1 * p[6], q11 = p[4] - f1 * p[7], q12 = p[5] - f1 * p[8];
        double q20 = p[6] - f2 * p[6], q21 = p[7] - f2 * p[7], q22 = p[8] - f2 * p[8];
        double t0 = s[0] + p[2] * rr, t1 = s[1] + p[5] * rr, t2 = s[2] + p[8] * rr;
        int pa = parent[j];
        if (pa < 0) continue;
        double kx = e[0], ky = e[1], cxx = e[2], cyy = e[3], lx = kx, ly = ky;
        double z0 = q00 * cxx + q01 * cyy + t0, z1 = q10 * cxx + q11 * cyy + t1;
        double z2 = q20 * cxx + q21 * cyy + t2;
        double c02 = kx * q00 + ky * q01 + q02, c12 = kx * q10 + ky * q11 + q12;
        double c22 = kx * q20 + ky * q21 + q22;
        double *a = P + 9 * pa, *bb = S + 3 * pa;
        a[0] += q00; a[1] += q01; a[2] += c02;
        a[3] += q10; a[4] += q11; a[5] += c12;
        a[6] += lx * q00 + ly * q10 + q20; a[7] += lx * q01 + ly * q11 + q21;
        a[8] += lx * c02 + ly * c12 + c22;
        bb[0] += z0; bb[1] += z1; bb[2] += lx * z0 + ly * z1 + z2;
    }
    for (int j = 0; j < nb; j++) {
        double o0 = 0.0, o1 = 0.0, o2 = 0.0;
        int pa = parent[j];
        if (pa >= 0) {
            const double *e = E + 6 * j, *ap = A + 3 * pa;
            o0 = ap[0] + e[0] * ap[2] + e[2];
            o1 = ap[1] + e[1] * ap[2] + e[3];
            o2 = ap[2];
        }
        const double *p = P + 9 * j, *s = S + 3 * j;
        double al = (T[j] - p[6] * o0 - p[7] * o1 - p[8] * o2 - s[2]) / D[j];
        A[3 * j] = o0; A[3 * j + 1] = o1; A[3 * j + 2] = o2 + al;
        out[j] = o2 + al;
    }
}

/* classical RK4 over n_steps (the step below is generated from ctmm.ode.rk4_step); state th, w
   updated in place; traj receives every store_every-th state ([th, w] rows), work has 25 nb +
   10 nb doubles */
int rk4(int nb, const int *parent, const double *ex, const double *ey, const double *cx,
        const double *cy, const double *m, const double *J, const double *k, const double *c,
        const double *r, const double *u, const double *g0, double gx, double gy, double h,
        int n_steps, int store_every, double *th, double *w, double *traj, double *work)
{
    double *a1 = work + 25 * nb, *a2 = a1 + nb, *a3 = a2 + nb, *a4 = a3 + nb;
    double *q2 = a4 + nb, *v2 = q2 + nb, *q3 = v2 + nb, *v3 = q3 + nb, *q4 = v3 + nb, *v4 = q4 + nb;
    int stored = 0;
    for (int step = 0; step < n_steps; step++) {
/*RK4_STEP*/
        if ((step + 1) % store_every == 0 || step + 1 == n_steps) {
            for (int i = 0; i < nb; i++) {
                if (!isfinite(th[i]) || !isfinite(w[i])) return -(step + 1);
                traj[stored * 2 * nb + i] = th[i];
                traj[stored * 2 * nb + nb + i] = w[i];
            }
            stored++;
        }
    }
    return stored;
}

int accelerations(int nb, const int *parent, const double *ex, const double *ey,
                  const double *cx, const double *cy, const double *m, const double *J,
                  const double *k, const double *c, const double *r, const double *u,
                  const double *g0, double gx, double gy, const double *th, const double *w,
                  double *out, double *work)
{
    accel(nb, parent, ex, ey, cx, cy, m, J, k, c, r, u, g0, gx, gy, th, w, out, work);
    return 0;
}
"""
C_SOURCE = C_SOURCE.replace("/*RK4_STEP*/", "\n".join(
    "        " + line for line in second_order_rk4_c(
        lambda q, v, a: f"accel(nb, parent, ex, ey, cx, cy, m, J, k, c, r, u, g0, gx, gy, {q}, {v}, {a}, work);"
    ).splitlines()))


@lru_cache(maxsize=1)
def library() -> ctypes.CDLL:
    """Compile (once, cached on disk by :mod:`ctmm.codegen`) and load the C kernel.

    Raises
    ------
    ModelError
        No C compiler, a compile error or an unusable cache folder (see :func:`ctmm.codegen.shared_library`).
    """
    lib = load_ctypes(C_SOURCE, "planar_rk4")
    dp = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    ip = np.ctypeslib.ndpointer(dtype=np.int32, flags="C_CONTIGUOUS")
    common = [ctypes.c_int, ip] + [dp] * 11 + [ctypes.c_double, ctypes.c_double]
    lib.rk4.argtypes = common + [ctypes.c_double, ctypes.c_int, ctypes.c_int, dp, dp, dp, dp]
    lib.rk4.restype = ctypes.c_int
    lib.accelerations.argtypes = common + [dp, dp, dp, dp]
    lib.accelerations.restype = ctypes.c_int
    return lib


def _arrays(model: PlanarModel) -> tuple:
    problems = []
    if np.any(model.joint_kind != REVOLUTE):
        problems.append("only revolute hinges (no driven hinges, no floating base)")
    if len(model.load_body):
        problems.append("no external loads")
    if model.beams:
        problems.append(f"rigid bodies only (not {', '.join(model.body_names[j] for j in model.beams)})")
    if not model._constant_laws:
        problems.append("constant hinge references and torques")
    if model.nonlinear_hinges:
        problems.append("linear hinge laws (nonlinear: " + ", ".join(model.joint_names[j] for j in model.nonlinear_hinges)
                        + "; the generated kernels, compiled=True, hold casadi-expressible ones)")
    if problems:
        raise ModelError(f"model {model.name!r} is not supported by the compiled kernel; it needs "
                         + ", ".join(problems) + "; use simulate_rk4 instead")
    reference, _, torque = model.hinge_laws(0.0)
    f = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    return (model.n_bodies, np.ascontiguousarray(model.parent, dtype=np.int32),
            f(model.end_vector[:, 0]), f(model.end_vector[:, 1]), f(model.com[:, 0]),
            f(model.com[:, 1]), f(model.mass), f(model.inertia), f(model.stiffness),
            f(model.damping), f(reference), f(torque), f(model.ground_angle),
            float(model.gravity[0]), float(model.gravity[1]))


def compiled_accelerations(model: PlanarModel, q, qdot) -> np.ndarray:
    """Accelerations from the C kernel (same result as :func:`ctmm.planar.accelerations`)."""
    args = _arrays(model)
    q, qdot = model.state(q, qdot)
    nb = model.n_bodies
    out = np.zeros(nb)
    library().accelerations(*args, np.ascontiguousarray(q, dtype=np.float64),
                            np.ascontiguousarray(qdot, dtype=np.float64), out, np.zeros(35 * nb))
    return out


def simulate_rk4_compiled(model: PlanarModel, q0, qdot0, *, t_final: float, dt: float,
                          store_every: int = 1, divergence_bound: float | None = None,
                          stability_check: str = "warn") -> PlanarSimulation:
    """RK4 + acceleration TMM with the whole time loop in compiled C (fixed scenes).

    Same arguments and result as :func:`ctmm.planar.integrate.simulate_rk4`; supports revolute
    trees with constant hinge laws and gravity (raises :class:`ModelError` otherwise).  The
    stability limit is checked before the run (linearisation by the C kernel); the divergence
    bound is checked on the stored states after the C loop, so a diverged run raises
    :class:`SimulationError` at the first stored state out of bound, with the history up to the
    last good stored state as ``partial_result``.  (The C loop itself stops at the first stored
    non-finite state.)
    """
    args = _arrays(model)
    q, v = initial_coordinates(model, q0, qdot0)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    store_every = check_store_every(store_every)
    guard = divergence_guard(model, q, divergence_bound)
    check_scheme(model, q, v, h, scheme="rk4", policy=stability_check,
                 accelerations=lambda m, a, b, t: compiled_accelerations(m, a, b))
    nb = model.n_bodies
    n_store = n_steps // store_every + (1 if n_steps % store_every else 0)
    traj = np.zeros((n_store, 2 * nb))
    work = np.zeros(35 * nb)
    th, w = q.copy(), v.copy()
    lib = library()
    start = _time.perf_counter()
    stored = lib.rk4(*args, h, n_steps, store_every, th, w, traj, work)
    wall = _time.perf_counter() - start
    steps = np.array([k for k in range(1, n_steps + 1) if k % store_every == 0 or k == n_steps])
    if stored < 0:      # non-finite at step -stored: the rows stored before it are good
        failed = -stored
        stored = (failed - 1) // store_every
        steps = np.append(steps[:stored], failed)
        traj[stored] = np.nan
        traj = traj[:stored + 1]
    t = np.concatenate([[0.0], steps * h])
    qs = np.vstack([q[None], traj[:, :nb]])
    vs = np.vstack([v[None], traj[:, nb:]])
    check_stored(guard, t, qs, vs, lambda k: PlanarSimulation(model, t[:k], qs[:k], vs[:k], "rk4-compiled", wall))
    return PlanarSimulation(model, t, qs, vs, "rk4-compiled", wall, n_evaluations=4 * n_steps)


__all__ = ["simulate_rk4_compiled", "compiled_accelerations", "library", "C_SOURCE"]
