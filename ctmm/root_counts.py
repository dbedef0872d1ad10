"""Counts of unstable characteristic roots for many parameter sets of one feedback loop.

The loop under study enters the characteristic function ``Delta(s)`` as an affine term
(:class:`ctmm.sweeps.LoopCharacteristic`); the counts are winding numbers along a certified
contour (:mod:`ctmm.counting_contour`, ``docs/stability.md``).  Shared by :mod:`ctmm.stability`
(which re-exports both names) and :mod:`ctmm.stability_chart`.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import validation
from .certification import ContourCertificate
from .control.loops import ControlledChain
from .counting_contour import build_contour, contour_height, count
from .errors import ModelError
from .state_space_characteristic import is_loop_system, loop_characteristic
from .sweeps import check_parameters, loop_weight_bound, n_sets

__all__ = ["RootCounts", "unstable_root_count", "region_certificate"]


def unstable_root_count(system: ControlledChain, *, loop: str | None = None, gain: Any = None,
                        delay: Any = None, weights: Any = None, sigma: float = 0.0,
                        im_max: float | None = None) -> np.ndarray:
    """Number of characteristic roots with ``Re s > sigma`` for many parameter sets of one loop.

    Parameters
    ----------
    system : ControlledChain, LinearizedSystem or ControlledModel
    loop : str, optional
        The loop whose parameters vary (default: the only loop).
    gain, delay : array_like, optional
        Gain factors ``k`` [-] (the loop gain itself for a static gain) and delays [s] (>= 0),
        broadcast together; default: the loop's current values.
    weights : array_like, optional
        Sensor weights, shape ``(n_sets, n_terms)`` or ``(n_terms,)``.
    sigma : float
        Count roots right of ``Re s = sigma`` [1/s] (0: unstable roots).
    im_max : float, optional
        Imaginary extent [rad/s] of the contour (default: the proven height, module
        :mod:`ctmm.certification`).

    Returns
    -------
    RootCounts
        Integer array of counts (with multiplicity); -1 where a root lies on the line
        ``Re s = sigma``.  ``counts.certificate`` says which region was counted and whether no
        root outside it can exist (:class:`~ctmm.certification.ContourCertificate`); a user
        ``im_max`` below the proven height that lets the loop term reach 1/2 warns
        (:class:`~ctmm.certification.StabilityWarning`).

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Free, Mass
    >>> from ctmm.control import ControlledChain, Feedback
    >>> plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    >>> system = ControlledChain(plant, [Feedback("pd", [("m.x", 1.0), ("m.v", 1.0)], "m", gain=1.0)])
    >>> unstable_root_count(system, delay=[0.0, 0.5, 1.5]).tolist()
    [0, 0, 2]
    """
    gain, delay = (None if v is None else validation.nonempty_array(n, v) for n, v in (("gain", gain), ("delay", delay)))
    model = loop_characteristic(system, loop)
    weights = None if weights is None else validation.weight_rows("weights", weights, model.weights.size)
    n = n_sets(gain, delay, weights)
    k, tau, w = model.parameters(n, None if gain is None else np.ravel(gain),
                                 None if delay is None else np.ravel(delay), weights)
    check_parameters(k, tau, w)
    sigma = validation.finite("sigma", sigma)
    contour = build_contour(model, loop_weight_bound(k, w), float(tau.max()), sigma=sigma, im_max=im_max)
    counts, _ = count(contour, k, tau, w)
    return RootCounts(counts, contour.certificate)


class RootCounts(np.ndarray):
    """Root counts (an integer array) with the :class:`~ctmm.certification.ContourCertificate`
    of the region they cover in its ``certificate`` attribute."""

    certificate: ContourCertificate | None

    def __new__(cls, counts: Any, certificate: ContourCertificate | None = None) -> "RootCounts":
        obj = np.asarray(counts).view(cls)
        obj.certificate = certificate
        return obj

    def __array_finalize__(self, obj: Any) -> None:
        self.certificate = getattr(obj, "certificate", None)


def region_certificate(system: Any, re_min: float, im_max: float) -> ContourCertificate | None:
    """Whether ``Re s > re_min, |Im s| <= im_max`` holds every root of a model with one (delayed) loop
    (:mod:`ctmm.certification`; warns when ``im_max`` is too small); None for other systems."""
    loops = getattr(system, "delays", getattr(system, "loops", ()))
    delayed = [lp.name for lp in loops if lp.delay]
    if not is_loop_system(system) or (len(loops) != 1 and len(delayed) != 1):
        return None
    try:
        model = loop_characteristic(system, delayed[0] if len(loops) > 1 else None)
    except ModelError:            # refused (a delay-free LTI loop beside it in a ControlledModel): no certificate
        return None
    k, tau, w = model.parameters(1)
    _, _, certificate = contour_height(model, loop_weight_bound(k, w), re_min, float(tau[0]), im_max)
    return certificate
