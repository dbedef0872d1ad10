"""The articulated sweep's frequency context of rigid trees as one compiled C kernel over bodies and frequencies.

:func:`ctmm.articulated.articulated_sweep` is written once for every context on :mod:`ctmm.ops`; on numpy its
per-body work is a few dozen calls on ``(B, d, d)`` batches, whose call overhead dominates.  For the frequency
context of trees whose bodies are rigid (``d`` unknowns each) and whose joints are welds, drives held at zero or
one free direction -- a unit axis (``JointTerms.axis``: planar hinges) or a column ``S`` (``d = 6``: spatial
revolute and prismatic joints) -- :class:`CompiledSweep` runs the same recursion frequency by frequency in C
(:data:`KERNEL_C`), every load case at once (spatial joints of more directions, below):

Tip to base, body ``j`` with ``P = Z_j + sum_children RF Phi_hat Kin``, ``p = h_j + sum_children RF psi_hat``:
joint on ``S`` (unit axis ``a``: row and column ``a`` of ``P``, no products): ``D = S^T P S + kappa``,
``w = (S^T P + G) / D``, ``r = (tau - S^T p) / D``, ``Phi_hat = P - (P S + H) w``, ``psi_hat = p + (P S + H) r``;
weld or held drive: ``Phi_hat = P``, ``psi_hat = p``.  Base to tip: ``A_O = Kin_e x_parent`` (ground 0),
``a = r - w . A_O``, ``x = A_O + S a``.

Both certificates of :mod:`ctmm.sweep_response` are decided in the kernel, per frequency: every pivot against
its terms (``|D| >= PIVOT_TOLERANCE (|s^2 m| + |D - s^2 m|)``, ``m`` the same pivot of the mass terms alone,
:func:`mass_pivots`) and the answer's a-posteriori backward error (the joint residuals of
``F_j = Z_j x_j + h_j + sum_children RF_c (F_c + H_c a_c)`` against the moduli of their terms, at most
``RESIDUAL_TOLERANCE``); a non-finite answer is not certified either.  Frequencies not certified are the
callers' (the dense resolvent), exactly as for the generic sweep.

Spatial trees (``d = 6``) with universal, spherical or free joints take the multi-direction variant
(:data:`ctmm.compiled_sweep_multi_kernel.KERNEL_MULTI_C`, its own C text, sharing the blocks of
:mod:`ctmm.compiled_sweep_kernel` that are the same: the one-direction variants are unchanged): every free joint on
the ``k`` columns of its ``S`` (``k x k`` laws, coupling ``G`` (k, 6) and ``H`` (6, k)), the same recursion with
``D`` a ``k x k`` block (Gaussian elimination with partial pivoting; an exactly singular block
leaves a non-finite answer, not certified) and the pivot certificate of the generic sweep on blocks
(:meth:`ctmm.sweep_response.ArticulatedResponse.pivots_certified`): the smallest singular value of ``D`` (one-sided
Jacobi rotations of its columns; 0 for a non-finite block) at least ``PIVOT_TOLERANCE (max|s^2 M_D| + max|D - s^2
M_D|)``, ``M_D`` the ``k x k`` mass pivot, largest moduli of the entries.  Its answers and certified frequencies are
checked against the generic sweep in ``tests/test_compiled_sweep_multi.py``.

The kernel is data-driven: the topology (parents, axes), the terms ``M0, C0, K0``, the point maps ``Kin, RF``,
the coupling ``G, H``, the joint laws, loads and frequencies are its arguments, so its code does not depend on
the model; it is compiled once per variant -- the point dimension ``d`` (a constant of the code) and the scalar
type -- and cached on disk by a hash of its text (:func:`ctmm.codegen.load_ctypes`).  Typed: the body terms,
point maps, coupling, body loads and mass pivots are ``double``; the Laplace variables, ``s^2``, the joint
laws and torques, the pivots and the answers are the variant's scalar: ``double`` (undamped terms on the
imaginary axis, real laws and loads: ``s^2 = -omega^2`` real, the same numbers as complex arithmetic) or C99
``double _Complex`` (damped or delayed terms; built with ``-fcx-fortran-rules``: products without the
NaN-recovery calls, quotients with range reduction; an overflow still shows as a non-finite answer, which is
not certified).

The recursion is written out here a second time beside the generic sweep (a hand-written C body, not traced
from :mod:`ctmm.ops`: casadi's symbols are real, and its traced step would not hold the complex variant); its
answers are checked against the generic sweep to round-off in ``tests/test_compiled_sweep.py``.  Without a C
compiler (:func:`ctmm.codegen.find_compiler`) the callers take the generic sweep; a compiler that fails to build
the kernel (:class:`~ctmm.errors.ModelError` from :func:`kernel_library`) is warned about by
:class:`ctmm.sweep_response.ArticulatedResponse`, and the generic sweep answers there too.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .articulated import Tree
from .codegen import find_compiler, load_ctypes
from .compiled_sweep_kernel import KERNEL_C
from .compiled_sweep_multi_kernel import KERNEL_MULTI_C
from .errors import ModelError

__all__ = ["COMPLEX_FLAGS", "CompiledSweep", "KERNEL_C", "LOAD_CASES", "REAL_FLAGS", "SweepAnswer", "applies",
           "compiler_present", "directions", "kernel_library", "kernel_source", "mass_pivots", "one_direction"]


LOAD_CASES = 16
"""Load cases one kernel call takes at most (more are swept in groups of this size)."""

REAL_FLAGS = ("-O3", "-shared", "-fPIC")
"""Compiler flags of the real variant (``-O3``: the inner loops over ``d`` and the load cases unrolled and
vectorised; measured in ``benchmarks/planar_frf.py`` at N = 100, 1.2x faster than ``-O2`` there; 0.55 s of
compiler CPU)."""
COMPLEX_FLAGS = ("-O3", "-fcx-fortran-rules", "-shared", "-fPIC")
"""Compiler flags of the complex variant (module docstring)."""


def compiler_present() -> bool:
    """True when :func:`ctmm.codegen.find_compiler` finds a C compiler (the kernel is then the default)."""
    try:
        find_compiler()
    except ModelError:
        return False
    return True


_ADDRESS, _INT, _DOUBLE = ctypes.c_void_p, ctypes.c_int, ctypes.c_double


def kernel_source(dimension: int, complex_scalar: bool, multi: bool = False) -> str:
    """The C text of one kernel variant (point ``dimension``, scalar type ``double _Complex`` or ``double``;
    ``multi``: joints of several directions, :data:`ctmm.compiled_sweep_multi_kernel.KERNEL_MULTI_C`).  Unit axes
    and joints on a column ``S`` share one text (the axes say which, :data:`KERNEL_C`)."""
    source = (KERNEL_MULTI_C if multi else KERNEL_C).replace("__DIM__", str(int(dimension)))
    source = source.replace("__COMPLEX__", "1" if complex_scalar else "0")
    return source.replace("__LMAX__", str(LOAD_CASES))


def kernel_library(dimension: int, complex_scalar: bool, multi: bool = False) -> ctypes.CDLL:
    """The compiled kernel of one variant (:func:`kernel_source`), from the disk cache or built now
    (:func:`ctmm.codegen.load_ctypes`; ModelError without a compiler or when the compile fails)."""
    name = f"ctmm_sweep_d{int(dimension)}_{'complex' if complex_scalar else 'real'}{'_multi' if multi else ''}"
    library = load_ctypes(kernel_source(dimension, complex_scalar, multi), name,
                          flags=COMPLEX_FLAGS if complex_scalar else REAL_FLAGS)
    library.sweep.restype = ctypes.c_int
    library.sweep.argtypes = [_INT] * 3 + [_ADDRESS] * 18 + [_DOUBLE] * 2 + [_ADDRESS] * 5
    library.mass_pivots.restype = None
    library.mass_pivots.argtypes = [_INT] + [_ADDRESS] * 8
    if multi:
        library.smallest_singular_values.restype = None
        library.smallest_singular_values.argtypes = [_INT, _INT, _ADDRESS, _ADDRESS]
    return library


def one_direction(joint: Any, dimension: int) -> bool:
    """True for a joint with one free direction the kernel takes: a unit axis (``axis``) or a real column ``S``
    of ``dimension`` rows (a spatial revolute or prismatic joint)."""
    return joint.free == 1 and (joint.axis is not None or (np.size(joint.S) == dimension
                                                           and not np.any(np.imag(joint.S))))


def directions(joint: Any, dimension: int) -> np.ndarray | None:
    """The real free directions ``S`` (dimension, k) of a spatial joint (``dimension`` 6) the multi-direction variant
    takes (``k >= 1``, laws ``k x k`` or, for ``k = 1``, scalars), else ``None``."""
    k = joint.free
    if dimension != 6 or not k or joint.axis is not None or np.size(joint.S) != dimension * k \
            or np.any(np.imag(joint.S)):
        return None
    for law in (joint.tau_q, joint.tau_v):
        if law is not None and np.size(law) != k * k:
            return None
    return np.real(np.asarray(joint.S)).reshape(dimension, k)


def applies(tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any], coupling: Sequence[Any] | None) -> bool:
    """True when :class:`CompiledSweep` takes these frequency-context terms: every body rigid (``M0`` of size
    ``d``), every joint a weld, a drive held at zero or one free direction (a unit ``axis`` or a column ``S``:
    :func:`one_direction`) without inertance, no joint offset ``c``, scalar joint laws, coupling (if any) only
    on one-direction joints; or, spatial (``d = 6``), free joints of several real directions (:func:`directions`:
    universal, spherical, free) with ``k x k`` laws and coupling ``G`` (k, 6), ``H`` (6, k)."""
    d = tree.dimension
    if d == 6 and any(joint.prescribed is None and joint.free > 1 for joint in joints):
        return _applies_multi(bodies, joints)
    for j, (M0, _, _, _, _) in enumerate(bodies):
        if M0.shape != (d, d):
            return False
        joint = joints[j]
        if joint.c is not None or joint.tau_a is not None:
            return False
        if any(law is not None and np.size(law) != 1 for law in (joint.tau_q, joint.tau_v)):
            return False
        if joint.prescribed is not None:
            if np.any(joint.prescribed):
                return False
        elif joint.free and not one_direction(joint, d):
            return False
        if coupling is not None and coupling[j] is not None and any(g is not None for g in coupling[j]) \
                and (not one_direction(joint, d) or joint.prescribed is not None):
            return False
    return True


def _applies_multi(bodies: Sequence[tuple], joints: Sequence[Any]) -> bool:
    """:func:`applies` for spatial trees with joints of several directions (the multi-direction variant)."""
    for (M0, _, _, _, _), joint in zip(bodies, joints):
        if M0.shape != (6, 6) or joint.c is not None or joint.tau_a is not None:
            return False
        if joint.prescribed is not None:
            if np.any(joint.prescribed):
                return False
        elif joint.free and directions(joint, 6) is None:
            return False
    return True


def _address(array: np.ndarray) -> int:
    """The address of a C-contiguous array's data (the caller keeps the array alive during the call)."""
    if not array.flags.c_contiguous:            # the kernel reads every array densely, row-major
        raise ValueError(f"the compiled sweep takes C-contiguous arrays, got strides {array.strides}")
    return array.ctypes.data


def mass_pivots(library: ctypes.CDLL, kernel: "CompiledSweep") -> np.ndarray:
    """(n,) the pivots of the mass terms alone (``Z = M0``, ``kappa = 0``, no coupling; 0 at bodies without a free
    joint): the scale the pivot certificate measures by."""
    out = np.zeros((kernel.n, kernel.d, kernel.d) if kernel.multi else kernel.n)
    work = np.zeros(kernel.n * kernel.d * kernel.d)
    library.mass_pivots(kernel.n, *(_address(a) for a in (kernel.parent, kernel.axis, kernel.direction, kernel.M0,
                                                             kernel.Kin, kernel.RF, out, work)))
    return out


@dataclass(frozen=True)
class SweepAnswer:
    """Result of :meth:`CompiledSweep.solve`.

    Attributes
    ----------
    x : ndarray, shape (n, d, L, B)
        ``A_in`` of every body (load cases, frequencies); a view.
    relative : ndarray, shape (F, L, B), or None
        The free joints' relative amplitudes ``a``, in :attr:`CompiledSweep.free` order, every direction of a joint
        (when asked for).
    pivot : ndarray, shape (J, B)
        ``D_j`` of the one-direction joints, in :attr:`CompiledSweep.free` order (multi-direction variant: the
        smallest singular value of each pivot block).
    backward : ndarray, shape (B,)
        The a-posteriori backward error of the answer.
    good : ndarray of bool, shape (B,)
        Both certificates passed and the answer finite.
    """

    x: np.ndarray
    relative: np.ndarray
    pivot: np.ndarray
    backward: np.ndarray
    good: np.ndarray


class CompiledSweep:
    """The frequency-context sweep of one tree's linearised terms by the compiled kernel, prepared once.

    Parameters
    ----------
    tree : Tree
    bodies : sequence of tuple
        ``(M0, C0, K0, Kin, RF)`` per body (``Kin``, ``RF``: dicts of ``(1, d, d)`` point maps).
    joints : sequence of JointTerms
        The held joints (``tau`` is the load cases' business: :meth:`solve`).
    coupling : sequence, optional
        ``(G_j, H_j)`` per joint or ``None`` (:func:`ctmm.articulated.articulated_inward`).

    Raises
    ------
    ModelError
        Terms the kernel does not take (:func:`applies`), no C compiler, or a failed compile.
    """

    def __init__(self, tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any],
                 coupling: Sequence[Any] | None = None) -> None:
        if not applies(tree, bodies, joints, coupling):
            raise ModelError("CompiledSweep: the terms are not those of a rigid tree on welds, held drives and "
                             "one-direction joints (ctmm.compiled_sweep.applies)")
        d = self.d = tree.dimension
        n = self.n = len(bodies)
        self.tree = tree
        self.parent = np.asarray(tree.parent, dtype=np.intc)
        self.M0, self.C0, self.K0 = (np.ascontiguousarray(np.stack([b[k] for b in bodies]), dtype=float)
                                     for k in range(3))
        self.damped_bodies = bool(np.any(self.C0))
        eye = np.eye(d)
        self.Kin, self.RF = np.tile(eye, (n, 1, 1)), np.tile(eye, (n, 1, 1))
        for j, parent in enumerate(tree.parent):
            if parent >= 0:
                e = tree.point[j]
                self.Kin[j], self.RF[j] = bodies[parent][3][e][0], bodies[parent][4][e][0]
        self.multi = d == 6 and any(joint.prescribed is None and joint.free > 1 for joint in joints)
        if self.multi:
            self._prepare_multi(joints, coupling)
            return
        # -1: weld or held drive; a >= 0: unit axis a; -2: the free direction S (``direction``)
        axis = [-1 if joint.prescribed is not None or not joint.free else -2 if joint.axis is None
                else int(joint.axis) for joint in joints]
        self.axis = np.asarray(axis, dtype=np.intc)
        self.free = [j for j, a in enumerate(axis) if a != -1]
        self.direction = np.zeros((n, d))
        for j, a in enumerate(axis):
            if a == -2:
                self.direction[j] = np.real(joints[j].S).reshape(d)
        self.G, self.H = np.zeros((n, d)), np.zeros((n, d))
        self.flags = np.zeros(n, dtype=np.intc)
        for j, pair in enumerate(coupling or ()):
            if pair is not None and axis[j] != -1:
                G, H = pair
                if G is not None:
                    self.G[j], self.flags[j] = np.asarray(G, dtype=float).reshape(d), self.flags[j] | 1
                if H is not None:
                    self.H[j], self.flags[j] = np.asarray(H, dtype=float).reshape(d), self.flags[j] | 2
        laws = np.zeros((2, n), dtype=complex)          # the joints' law tangents tau_q, tau_v (-k, -c)
        for j in self.free:
            for k, law in enumerate((joints[j].tau_q, joints[j].tau_v)):
                if law is not None:
                    laws[k, j] = complex(np.asarray(law).reshape(-1)[0])
        self._build(laws)

    def _build(self, laws: np.ndarray) -> None:
        """The joints' laws (``laws[0]``, ``laws[1]``: ``-stiffness``, ``-damping`` tangents), the arrays' addresses,
        the kernel variants and the mass pivots, once the terms are set."""
        self.real_laws = not np.any(laws.imag)
        self.stiffness, self.damping = laws[0].copy(), laws[1].copy()   # kappa = -(stiffness + damping s)
        self.undamped = not self.damped_bodies and not np.any(self.damping)
        self.addresses = tuple(_address(a) for a in (self.parent, self.axis))
        self.terms = tuple(_address(a) for a in (self.M0, self.C0, self.K0, self.Kin, self.RF, self.G, self.H,
                                                  self.direction))
        self.libraries: dict = {}
        self.library(False)
        if not self.undamped or not self.real_laws:     # the complex variant answers every call: built now
            self.library(True)
        self.mass_pivot = mass_pivots(self.libraries[False], self)

    def _prepare_multi(self, joints: Sequence[Any], coupling: Sequence[Any] | None) -> None:
        """The terms of the multi-direction variant: every free joint on the ``k`` columns of its ``S``, joint blocks
        padded to ``d x d`` (``axis`` holds ``k``, 0 for welds and held drives)."""
        d, n = self.d, self.n
        count = [0 if joint.prescribed is not None else joint.free for joint in joints]
        self.axis = np.asarray(count, dtype=np.intc)
        self.free = [j for j, k in enumerate(count) if k]
        self.slots = [(j, c) for j in self.free for c in range(count[j])]
        self.direction = np.zeros((n, d, d))
        laws = np.zeros((2, n, d, d), dtype=complex)    # tau_q, tau_v (k x k) of joints with a law (frequency_kappa)
        for j in self.free:
            k = count[j]
            self.direction[j, :, :k] = directions(joints[j], d)
            for i, law in enumerate((joints[j].tau_q, joints[j].tau_v)):
                if law is not None and joints[j].tau is not None:
                    laws[i, j, :k, :k] = np.asarray(law).reshape(k, k)
        self.G, self.H = np.zeros((n, d, d)), np.zeros((n, d, d))
        self.flags = np.zeros(n, dtype=np.intc)
        for j, pair in enumerate(coupling or ()):
            if pair is not None and count[j]:
                k, (G, H) = count[j], pair
                if G is not None:
                    self.G[j, :k], self.flags[j] = np.real(np.asarray(G)).reshape(k, d), self.flags[j] | 1
                if H is not None:
                    self.H[j, :, :k], self.flags[j] = np.real(np.asarray(H)).reshape(d, k), self.flags[j] | 2
        self._build(laws)

    def library(self, complex_scalar: bool) -> ctypes.CDLL:
        """The kernel variant (compiled or loaded on first use)."""
        if complex_scalar not in self.libraries:
            self.libraries[complex_scalar] = kernel_library(self.d, complex_scalar, self.multi)
        return self.libraries[complex_scalar]

    def _call(self, complex_scalar: bool, L: int, B: int, flags: np.ndarray, inputs: tuple, tolerances: tuple,
              x: np.ndarray, amplitudes: np.ndarray | None, outputs: tuple) -> None:
        """One call of the kernel variant on ``L`` load cases at ``B`` frequencies (the arrays of :meth:`solve`)."""
        n = self.n
        status = self.library(complex_scalar).sweep(
            n, L, B, *self.addresses, _address(flags), *self.terms, *(_address(a) for a in inputs), *tolerances,
            _address(x), None if amplitudes is None else _address(amplitudes), *(_address(a) for a in outputs))
        if status == -1:
            raise MemoryError(f"the compiled sweep could not allocate its work space ({n} bodies, {L} load cases)")
        if status != 0:
            raise ModelError(f"CompiledSweep.solve: {L} load cases; the kernel takes 1 to {LOAD_CASES} at once")

    def torques(self, joints_of_cases: Sequence[Sequence[Any]]) -> np.ndarray:
        """(F, L) complex: the free joints' torques ``tau`` of each load case's joint terms, every direction of a
        joint (the rows of :meth:`solve`'s ``torques``)."""
        rows = self.slots if self.multi else [(j, 0) for j in self.free]
        tau = np.zeros((len(rows), len(joints_of_cases)), dtype=complex)
        for i, joints in enumerate(joints_of_cases):
            for r, (j, c) in enumerate(rows):
                if joints[j].tau is not None:
                    tau[r, i] = np.asarray(joints[j].tau).reshape(-1)[c]
        return tau

    def solve(self, s: np.ndarray, loads: np.ndarray, torques: np.ndarray, *, pivot_tolerance: float,
              residual_tolerance: float, relative: bool = False) -> SweepAnswer:
        """The sweep at the Laplace variables ``s`` (B,) for the load cases ``loads`` (n, d, L) (body load columns
        ``h``, real) and ``torques`` (F, L) (the one-direction joints' ``tau``, in :attr:`free` order), with both
        certificates decided at ``pivot_tolerance`` and ``residual_tolerance`` (module docstring), and with
        ``relative`` the joints' relative amplitudes.  Real arithmetic where every term is real (undamped, ``s`` on
        the imaginary axis, real laws and torques)."""
        d, n = self.d, self.n
        s = np.ascontiguousarray(np.asarray(s, dtype=complex).reshape(-1))
        if np.any(np.imag(loads)):
            raise ModelError("CompiledSweep.solve: loads must be real body load columns (the planar ports' are)")
        loads = np.ascontiguousarray(np.real(loads), dtype=float)
        torques = np.asarray(torques)
        real = self.undamped and not np.any(s.real) and self.real_laws and not np.any(np.imag(torques))
        dtype = float if real else complex
        L = loads.shape[2]
        if L > LOAD_CASES:                          # groups of LOAD_CASES load cases
            parts = [self.solve(s, loads[:, :, k:k + LOAD_CASES], torques[:, k:k + LOAD_CASES], relative=relative,
                                pivot_tolerance=pivot_tolerance, residual_tolerance=residual_tolerance)
                     for k in range(0, L, LOAD_CASES)]
            backward = np.max([part.backward for part in parts], axis=0)
            good = np.all([part.good for part in parts], axis=0)
            amplitudes = np.concatenate([part.relative for part in parts], axis=1) if relative else None
            return SweepAnswer(np.concatenate([part.x for part in parts], axis=2), amplitudes, parts[0].pivot,
                               backward, good)
        if self.multi:
            return self._solve_multi(s, loads, torques, real, pivot_tolerance, residual_tolerance, relative)
        torque = np.zeros((n, L), dtype=dtype)
        torque[self.free] = torques.real if real else torques
        flags = self.flags | np.where(np.any(torque != 0.0, axis=1), 4, 0).astype(np.intc)
        squared = ((s * s).real if real else s * s).astype(dtype)
        rate = np.zeros(s.size) if real else s
        stiffness = self.stiffness.real.copy() if real else self.stiffness
        damping = self.damping.real.copy() if real else self.damping
        x = np.empty((s.size, n, d, L), dtype=dtype)
        amplitudes = np.empty((s.size, n, L), dtype=dtype) if relative else None
        pivot = np.empty((s.size, n), dtype=dtype)
        backward, good = np.empty(s.size), np.empty(s.size, dtype=np.intc)
        self._call(not real, L, s.size, flags, (stiffness, damping, self.mass_pivot, loads, torque, squared, rate),
                   (pivot_tolerance, residual_tolerance), x, amplitudes, (pivot, backward, good))
        relative_amplitudes = None if amplitudes is None else amplitudes[:, self.free].transpose(1, 2, 0)
        return SweepAnswer(x.transpose(1, 2, 3, 0), relative_amplitudes, pivot[:, self.free].T, backward,
                           good.astype(bool))

    def _solve_multi(self, s: np.ndarray, loads: np.ndarray, torques: np.ndarray, real: bool, pivot_tolerance: float,
                     residual_tolerance: float, relative: bool) -> SweepAnswer:
        """:meth:`solve` of one group of load cases by the multi-direction variant."""
        d, n, L = self.d, self.n, loads.shape[2]
        dtype = float if real else complex
        torque = np.zeros((n, d, L), dtype=dtype)
        for r, (j, c) in enumerate(self.slots):
            torque[j, c] = torques[r].real if real else torques[r]
        flags = self.flags.copy()
        squared = ((s * s).real if real else s * s).astype(dtype)
        rate = np.zeros(s.size) if real else s
        stiffness = np.ascontiguousarray(self.stiffness.real if real else self.stiffness)
        damping = np.ascontiguousarray(self.damping.real if real else self.damping)
        x = np.empty((s.size, n, d, L), dtype=dtype)
        amplitudes = np.empty((s.size, n, d, L), dtype=dtype) if relative else None
        pivot = np.empty((s.size, n))
        backward, good = np.empty(s.size), np.empty(s.size, dtype=np.intc)
        self._call(not real, L, s.size, flags, (stiffness, damping, self.mass_pivot, loads, torque, squared, rate),
                   (pivot_tolerance, residual_tolerance), x, amplitudes, (pivot, backward, good))
        relative_amplitudes = None
        if amplitudes is not None:
            joint, direction = (np.array([slot[k] for slot in self.slots], dtype=int) for k in (0, 1))
            relative_amplitudes = amplitudes[:, joint, direction].transpose(1, 2, 0)
        return SweepAnswer(x.transpose(1, 2, 3, 0), relative_amplitudes, pivot[:, self.free].T, backward,
                           good.astype(bool))
