"""Step-size stability limit of a chain simulation, checked before the run starts.

A conditionally stable scheme (Newmark-beta with ``2 beta < gamma``, Wilson-theta with
``theta < 1.37``) is stable only while ``omega_max dt`` stays below the scheme's limit
(:meth:`ctmm.schemes.Scheme.stability_limit`), where ``omega_max`` [rad/s] is the highest natural
frequency of the model.  This module finds ``omega_max`` for a 1-D lumped chain and compares:

1. a cheap **upper bound** ``sqrt(2 k_i / m_i)`` (largest over the mass nodes, with ``k_i`` the
   stiffness attached to node ``i``: connectors on both sides and grounded springs).  By
   Gershgorin's theorem on the statically condensed stiffness matrix (condensing massless
   junctions keeps its rows diagonally dominant and never increases a diagonal term), every
   undamped natural frequency is below it.  When the bound is within the limit, the run is
   certified without further work;
2. otherwise the **exact** highest natural frequency of the undamped chain (same masses and
   stiffnesses, dampers removed), isolated by bisection on :func:`ctmm.eigenvalue_count`
   (Wittrick-Williams counts, no root can be missed).  A chain that has no undamped version
   (a pure damper connector or boundary) keeps the upper bound, which can only warn too early.

Damping is left out on purpose: for the schemes concerned, zero damping is the case whose
limit is the smallest (Hughes, *The Finite Element Method*, §9.1).  Closed-loop feedback is not
included: a loop changes the frequencies of the plant (the divergence guard of the run catches
what this check cannot see).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from .elements.boundary import Elastic
from .elements.lumped import Connector, PointElement
from .errors import ModelError
from .guard import StabilityLimitWarning, check_step
from .natural import eigenvalue_count
from .schemes import Scheme
from .system import Chain

__all__ = ["frequency_bound", "highest_natural_frequency", "check_scheme_step"]

_POLICIES = ("warn", "error", "ignore")


def _is_lumped(system: Chain) -> bool:
    """A 1-D chain of springs, dampers and point elements (the bound below holds for it).

    Connectors with inertance (inerters) couple the masses: the bound and the undamped copy do
    not cover them, so their chains take the "cannot be checked" path.
    """
    coefficients = [e.lumped_coefficients() for e in system.body]
    return system.layout.size == 2 and all(c is not None and not (c.connector and c.mass > 0.0)
                                           for c in coefficients)


def frequency_bound(system: Chain) -> float:
    """Upper bound [rad/s] on every undamped natural frequency of a 1-D lumped chain.

    Parameters
    ----------
    system : Chain
        A chain of :class:`~ctmm.elements.lumped.PointElement` and
        :class:`~ctmm.elements.lumped.Connector` elements.

    Returns
    -------
    float
        ``max_i sqrt(2 k_i / m_i)`` over the points with mass (0 if none has mass and stiffness).
    """
    body = system.body
    node = np.zeros(system.n_points, dtype=int)   # consecutive points joined by point elements coincide
    for j, e in enumerate(body, start=1):          # element j lies between points j-1 and j
        node[j] = node[j - 1] if isinstance(e, PointElement) else node[j - 1] + 1
    node_mass = np.zeros(node[-1] + 1)
    node_stiffness = np.zeros(node[-1] + 1)
    for j, e in enumerate(body, start=1):
        if isinstance(e, PointElement):
            node_mass[node[j - 1]] += e.mass
            node_stiffness[node[j - 1]] += e.stiffness
        else:
            node_stiffness[node[j - 1]] += e.stiffness
            node_stiffness[node[j]] += e.stiffness
    for boundary, point in ((system.start, 0), (system.end, -1)):
        if isinstance(boundary, Elastic):
            node_stiffness[node[point]] += boundary.stiffness
    massive = node_mass > 0.0
    if not np.any(massive):
        return 0.0
    return float(np.sqrt(np.max(2.0 * node_stiffness[massive] / node_mass[massive])))


def _undamped(system: Chain) -> Chain | None:
    """The chain with its dampers removed, or None when a damper cannot be removed."""
    body = []
    for e in system.body:
        if isinstance(e, PointElement):
            body.append(PointElement(e.name, mass=e.mass, stiffness=e.stiffness))
        elif e.stiffness > 0.0:
            body.append(Connector(e.name, stiffness=e.stiffness, free_length=e.free_length))
        else:
            return None
    ends = []
    for boundary in (system.start, system.end):
        if getattr(boundary, "damping", 0.0):
            if not isinstance(boundary, Elastic) or boundary.stiffness == 0.0:
                return None
            boundary = Elastic(boundary.name, boundary.stiffness, anchor=boundary.anchor)
        ends.append(boundary)
    return Chain(system.name + "(undamped)", [ends[0], *body, ends[1]])


def highest_natural_frequency(system: Chain, *, rtol: float = 1e-6) -> tuple[float, bool]:
    """Highest undamped natural frequency [rad/s] of a 1-D lumped chain, or an upper bound.

    Parameters
    ----------
    system : Chain
        A lumped 1-D chain.
    rtol : float
        Relative width of the final bracket; its upper end is returned (never below the root).

    Returns
    -------
    (float, bool)
        ``omega_max`` and whether it is exact (``False``: the upper bound of
        :func:`frequency_bound`, for chains without an undamped version).
    """
    bound = frequency_bound(system)
    undamped = _undamped(system)
    if undamped is None or bound == 0.0:
        return bound, False
    top = 1.01 * bound
    total = int(eigenvalue_count(undamped, [top])[0])
    if total == 0:
        return 0.0, True
    low, high = 0.0, top
    while high - low > rtol * high:
        grid = np.linspace(low, high, 33)[1:]
        counts = eigenvalue_count(undamped, grid)
        first = int(np.argmax(counts >= total))  # first grid point with every root below it
        high = float(grid[first])
        low = float(grid[first - 1]) if first > 0 else low
    return high, True


def check_scheme_step(system: Chain, scheme: Scheme, dt: float, policy: str | None) -> str | None:
    """Check ``dt`` against the stability limit of ``scheme`` for ``system`` before a run.

    Parameters
    ----------
    system : Chain
        The (uncontrolled) chain.
    scheme : Scheme
        The integrator.
    dt : float
        Step size [s].
    policy : {"warn", "error", "ignore"} or None
        ``None`` (default of the simulators): ``"error"`` when no step is stable (the scheme
        amplifies every undamped mode, e.g. Newmark with ``gamma < 1/2``), ``"warn"`` when the
        step exceeds a finite limit.  A warning is a
        :class:`~ctmm.guard.StabilityLimitWarning`.

    Returns
    -------
    str or None
        The message issued, or ``None`` when the step is certified (or the check is ignored).

    Raises
    ------
    ModelError
        Unknown policy, or the limit is exceeded and the policy is ``"error"``.
    """
    if policy is not None and policy not in _POLICIES:
        raise ModelError(f"stability_check must be 'warn', 'error', 'ignore' or None, got {policy!r}")
    limit = scheme.stability_limit()
    if policy == "ignore" or math.isinf(limit):
        return None
    effective = policy or ("error" if limit == 0.0 else "warn")
    what = repr(scheme)
    if not _is_lumped(system):
        message = (f"{what} is only conditionally stable (omega dt <= {limit:.4g}) and the step cannot be "
                   "checked: the chain has distributed elements (natural frequencies unbounded) or inerters; "
                   "use an unconditionally stable scheme (Newmark(0.25, 0.5), generalized_alpha, houbolt)")
        if effective == "error":
            raise ModelError(message)
        warnings.warn(message, StabilityLimitWarning, stacklevel=3)
        return message
    if frequency_bound(system) * dt <= limit:
        return None
    omega_max, exact = highest_natural_frequency(system)
    return check_step(what if exact else f"{what} (against an upper bound of the highest frequency)",
                      omega_max, dt, limit, policy=effective)
