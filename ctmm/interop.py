"""Export to python-control: frequency-response data and state-space realisations of any ctmm model.

* :func:`to_frd` -- a :class:`control.FrequencyResponseData` from a
  :class:`~ctmm.results.FrequencyResponse` or directly from any system that
  :func:`ctmm.frequency_response` takes (chains, planar, spatial and controlled models); exact delays
  survive because the data are the TMM's own values ``C(iw) e^{-i w tau}``.
* :func:`to_state_space` -- a :class:`control.StateSpace` of a *delay-free* model: a lumped
  (controlled) 1-D chain is realised from its element parameters
  (:func:`ctmm.lumped_realisation.chain_state_space`); a planar, spatial, kinematic-loop or controlled
  model is linearised about its static equilibrium by :func:`ctmm.linearize` (or give a
  :class:`~ctmm.linearized.LinearizedSystem` you made).  This is an export (to use python-control's
  design tools, ``lqr``, ``feedback``, time responses), not an independent reference: the references
  live in :mod:`ctmm.reference`.  Loops with a delay have no finite-dimensional realisation and are
  refused by name: use :func:`to_frd`, which is exact, or apply ``control.pade`` yourself.
"""
from __future__ import annotations

from typing import Any, Sequence

from .errors import ModelError
from .linearize import linearize
from .linearized import LinearizedSystem, control_name
from .lumped_realisation import assemble_matrices, chain_state_space, default_signal_names
from .results import FrequencyResponse
from .system import Chain, require_system

__all__ = ["to_frd", "to_state_space", "assemble_matrices", "control_name", "default_signal_names"]


# -------------------------------------------------------------------------------------- FRD
def to_frd(source: Any, omega: Any = None, *, inputs: str | Sequence[str] | None = None,
           outputs: str | Sequence[str] | None = None):
    """python-control frequency-response data of a ctmm response or system.

    Parameters
    ----------
    source : FrequencyResponse or Chain or ControlledChain
        A computed response (converted as is), or a system evaluated with
        :func:`ctmm.frequency_response` on ``omega``.
    omega : array_like, optional
        Angular frequencies [rad/s] (required with a system, not allowed with a response).
    inputs, outputs : str or sequence of str, optional
        Signal names (required with a system).

    Returns
    -------
    control.FrequencyResponseData
        SISO when one input and one output, else MIMO; labels from :func:`control_name`; ``omega``
        ascending, a repeated frequency kept once (:meth:`FrequencyResponse.to_control`).

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    >>> frd = to_frd(chain, [1.0, 5.0], inputs="m.force", outputs="m.x")
    >>> complex(frd(5j))  # doctest: +ELLIPSIS
    (0.0133...+0j)
    """
    if isinstance(source, FrequencyResponse):
        if omega is not None or inputs is not None or outputs is not None:
            raise ModelError("to_frd(FrequencyResponse) takes no omega/inputs/outputs; "
                             "they are those of the response")
        response = source
    else:
        if omega is None or inputs is None or outputs is None:
            raise ModelError("to_frd(system, omega, inputs=..., outputs=...) needs omega [rad/s], inputs "
                             f"and outputs, got omega={omega!r}, inputs={inputs!r}, outputs={outputs!r}")
        require_system(source, parameter="source")
        from .frequency import frequency_response

        response = frequency_response(source, omega, input=inputs, output=outputs)
    return response.to_control()        # ascending, distinct frequencies, as python-control's FRD needs


# -------------------------------------------------------------------------- state space
def to_state_space(system: Any, *, inputs: str | Sequence[str] | None = None,
                   outputs: str | Sequence[str] | None = None):
    """python-control state-space model of a delay-free ctmm model.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel, KinematicLoopModel, ControlledModel or LinearizedSystem
        A lumped chain (with loops without delay) is realised exactly from its element parameters
        (:func:`ctmm.lumped_realisation.chain_state_space`: states ``"<mass>_x"``, ``"<mass>_v"``,
        controller states); any other model is linearised about its static equilibrium by
        :func:`ctmm.linearize` (call :func:`ctmm.linearize` yourself for another operating point and
        pass the :class:`~ctmm.linearized.LinearizedSystem`).
    inputs, outputs : str or sequence of str, optional
        Signal names as in :func:`ctmm.linearize` (chains: force inputs ``"m2.force"``, loop references
        ``"<loop>.reference"``; outputs ``"m6.x"``, ``"k3.f"``, ``"<loop>.y"``, ``"<loop>.u"``; planar
        and spatial models: actuator and sensor port names).  Not allowed with a ``LinearizedSystem``
        (its ports are fixed).

    Returns
    -------
    control.StateSpace
        Continuous time, labelled with the ctmm names through :func:`control_name` (``"m6.x"`` ->
        ``"m6_x"``; python-control reserves dots).

    Raises
    ------
    ModelError
        A loop with a delay (no finite-dimensional realisation: use :func:`to_frd` or ``control.pade``),
        a chain with distributed elements (beam fields), or what :func:`ctmm.linearize` refuses.

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    >>> ss = to_state_space(chain, inputs="m.force", outputs="m.x")
    >>> complex(np.squeeze(ss(5j)))  # doctest: +ELLIPSIS
    (0.0133...+0j)
    """
    if isinstance(system, LinearizedSystem):
        if inputs is not None or outputs is not None:
            raise ModelError(f"to_state_space(LinearizedSystem) takes no inputs/outputs (got inputs={inputs!r}, "
                             f"outputs={outputs!r}); they are those of the linearisation: pass them to ctmm.linearize")
        linear = system
    else:
        plant = getattr(system, "plant", system)
        if isinstance(plant, Chain):
            return chain_state_space(system, inputs=inputs, outputs=outputs)
        linear = linearize(system, inputs=inputs, outputs=outputs)
    if linear.delays:
        names = ", ".join(f"{loop.name!r} (delay {loop.delay!r} s)" for loop in linear.delays)
        raise ModelError(f"loops {names} have a delay: no finite-dimensional realisation; use to_frd (exact) or "
                         "approximate e^(-s tau) with control.pade and close the loop on ctmm.linearize's open ports")
    return linear.state_space
