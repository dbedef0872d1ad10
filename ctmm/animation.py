"""Animations of planar and spatial runs: bodies as lines through their points, beams deformed, hinges as dots.

:func:`mechanism_frames` turns a :class:`~ctmm.results.SimulationResult` of a planar, flexible or
spatial model into drawing data (polylines of every body in world coordinates [m], joint
positions [m]) at chosen sample rows; :func:`animate` draws them with matplotlib and writes a GIF
(Pillow) or an MP4 (ffmpeg). ``SimulationResult.animate(path, ...)`` calls :func:`animate`.

A planar model computes its points itself (``model.points``); a spatial run is drawn from the world
positions of its body points stored in the result (:func:`drawing_outputs`), because this module,
reached from :mod:`ctmm.results`, may not import :mod:`ctmm.spatial` (which imports the results:
an import cycle); :mod:`ctmm.animation_spatial` adds them to a run that lacks them.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .errors import ModelError

__all__ = ["Frame", "mechanism_frames", "frame_rows", "drawing_outputs", "animate", "WRITERS"]

WRITERS = {".gif": "pillow", ".mp4": "ffmpeg"}
"""File endings :func:`animate` writes and the matplotlib writer of each."""


@dataclass(frozen=True)
class Frame:
    """The mechanism at one time.

    Attributes
    ----------
    time : float
        Time [s].
    bodies : dict
        ``{body name: (k, d) array}``: a polyline through the body's points in world
        coordinates [m] (``d`` = 2 planar, 3 spatial): inboard point, then each outboard point (rigid
        bodies, returning to the inboard point between ends), the deformed stations (beams) or the
        deformed nodes in their order (finite-element subsystems).
    joints : ndarray
        ``(n_joints, d)`` positions of the hinges / joints (the inboard points) [m].
    """

    time: float
    bodies: dict
    joints: np.ndarray


def _model(result: Any) -> Any:
    system = getattr(result, "system", None)
    model = getattr(system, "model", None)
    model = getattr(model, "plant", model)           # a controlled model: draw its plant
    kind = type(model).__name__
    if kind not in ("PlanarModel", "SpatialModel"):
        raise ModelError(f"animate: the result must be a run of a planar or spatial model (ctmm.simulate), got a "
                         f"result of {type(system).__name__ if model is None else kind}; a 1-D chain has no "
                         "geometry to draw (plot its signals with result.plot)")
    return model


def frame_rows(n_rows: int, frames: int | None) -> np.ndarray:
    """Indices of ``frames`` sample rows evenly spread over ``n_rows`` (all rows when ``frames`` is None)."""
    if frames is None:
        return np.arange(n_rows)
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
        raise ModelError(f"frames must be an integer >= 1 (number of pictures) or None for every stored row, "
                         f"got {frames!r}")
    return np.unique(np.round(np.linspace(0, n_rows - 1, min(int(frames), n_rows))).astype(int))


def _finite_elements_planar(body: Any) -> bool:
    """Whether a deformable planar body is a finite-element subsystem (:class:`ctmm.fem.GlobalSubsystem`)."""
    return hasattr(body, "node_dofs") and hasattr(getattr(body, "data", None), "keep")


def _deformed_nodes(body: Any, eta: np.ndarray, exaggeration: float) -> np.ndarray:
    """``(n_nodes, 2)`` frame positions ``X + exaggeration u`` [m] of a planar finite-element subsystem's nodes
    in their order, ``u`` their displacements among the internal coordinates ``eta`` (0 for nodes held in
    the frame)."""
    data = body.data
    internal = {int(i): k for k, i in enumerate(data.keep)}
    return np.array([np.asarray(data.position[node], float)[:2] + exaggeration * np.array(
        [eta[internal[i]] if i in internal else 0.0 for i in dofs[:2]]) for node, dofs in body.node_dofs.items()])


def _planar_frames(model: Any, result: Any, rows: np.ndarray, stations: int, exaggeration: float) -> list[Frame]:
    n_rows = len(result.time)
    q = np.array([result[name] for name in model.coordinates], dtype=float).reshape(-1, n_rows).T
    qdot = np.array([result[name + "_dot"] for name in model.coordinates], dtype=float).reshape(-1, n_rows).T
    frames = []
    for row in rows:
        t = float(result.time[row])
        points = model.points(q[row], qdot[row], t)
        bodies = {}
        for i, name in enumerate(model.body_names):
            c, s = np.cos(points["theta"][i]), np.sin(points["theta"][i])
            rotation = np.array([[c, -s], [s, c]])
            inboard = points["inboard"][i]
            if i in model.beams and _finite_elements_planar(model.beams[i]):
                local = _deformed_nodes(model.beams[i], q[row][model.modal_index[i]], exaggeration)
            elif i in model.beams:
                beam = model.beams[i]
                x = np.linspace(0.0, beam.length, stations)
                eta = q[row][model.modal_index[i]]
                nq = beam.data.nq
                axial = beam.axial_shapes(x).T @ eta[nq:] if len(eta) > nq else 0.0
                local = np.column_stack([x + exaggeration * axial, exaggeration * (beam.shapes(x).T @ eta[:nq])])
            else:
                ends = [np.asarray(v, float) for v in model.ends[i].values()]
                local = [np.zeros(2)]
                for end in ends:
                    local += [end, np.zeros(2)]
                local = np.array(local[:-1] if ends else [np.zeros(2), model.com[i]])
            bodies[name] = inboard + local @ rotation.T
        frames.append(Frame(t, bodies, np.array(points["inboard"])))
    return frames


def _finite_elements(body: Any) -> bool:
    """Whether a spatial body is a finite-element subsystem (nodes that move in its frame)."""
    return hasattr(body, "deformed_point") and isinstance(getattr(body, "nodes", None), Mapping)


def _drawn_points(body: Any) -> list[str]:
    """The points a spatial body is drawn through after ``origin``: every node of a finite-element subsystem
    (:class:`ctmm.fem.SpatialSubsystem`, in the order of its nodes), else the named points (the centre of mass
    when the body names none)."""
    if _finite_elements(body):
        return [node for node in body.nodes if node != "origin"]
    return [p for p in body.points if p != "origin"] or ["com"]


def drawing_outputs(model: Any) -> list[str]:
    """The signals a spatial run needs for drawing: world positions [m] of every body's points.

    ``"<body>.<point>.x|y|z"`` for the ``origin`` and each named point (the centre of mass when a
    body names none; every node of a finite-element subsystem, deformed); pass them as
    ``ctmm.simulate(model, ..., outputs=drawing_outputs(model))``, or add them to a finished run with
    :func:`ctmm.animation_spatial.with_pose_signals`.
    """
    names = []
    for body in getattr(model, "bodies", ()):
        names += [f"{body.name}.{point}.{axis}" for point in ["origin", *_drawn_points(body)] for axis in "xyz"]
    return names


def _spatial_frames(model: Any, result: Any, rows: np.ndarray) -> list[Frame]:
    needed = drawing_outputs(model)
    missing = [name for name in needed if name not in result.extra]
    if missing:
        raise ModelError(f"a spatial run is drawn from the world positions of its bodies' points, which this result "
                         f"does not hold ({missing[0]!r} and {len(missing) - 1} more): simulate with "
                         "outputs=ctmm.animation.drawing_outputs(model), or add them with "
                         "ctmm.animation_spatial.with_pose_signals(result)")
    frames = []
    for row in rows:
        bodies, joints = {}, []
        for body in model.bodies:
            points = _drawn_points(body)
            position = {p: np.array([result[f"{body.name}.{p}.{axis}"][row] for axis in "xyz"])
                        for p in ["origin", *points]}
            if _finite_elements(body):
                bodies[body.name] = np.array([position[p] for p in points])        # through its deformed nodes
            else:
                polyline = [position["origin"]]
                for point in points:
                    polyline += [position[point], position["origin"]]
                bodies[body.name] = np.array(polyline[:-1])
            joints.append(position["origin"])
        frames.append(Frame(float(result.time[row]), bodies, np.array(joints)))
    return frames


def mechanism_frames(result: Any, rows: Sequence[int] | None = None, *, stations: int = 21,
                     exaggeration: float = 1.0) -> list[Frame]:
    """The mechanism drawn at sample ``rows`` of a planar or spatial run.

    Parameters
    ----------
    result : SimulationResult
        Of :func:`ctmm.simulate` on a ``PlanarModel`` (rigid bodies, modal beams), a ``SpatialModel``
        or a controlled model built on one.
    rows : sequence of int, optional
        Sample rows (default: every row).
    stations : int
        Points along each beam [-] (>= 2).
    exaggeration : float
        Factor on the beams' deformation (axial and transverse) [-], > 0: 1 draws it true to scale;
        the bodies carried by a beam's tip are placed by the true deformation.

    Returns
    -------
    list of Frame
        Positions in world coordinates [m]; spatial time-dependent joint laws enter only through the
        stored coordinates (joint positions are read from the run, not recomputed).
    """
    model = _model(result)
    rows = np.arange(len(result.time)) if rows is None else np.asarray(rows, dtype=int)
    if rows.size == 0 or rows.min() < 0 or rows.max() >= len(result.time):
        raise ModelError(f"rows must be sample rows 0 ... {len(result.time) - 1} of the result, got {rows.tolist()}")
    if isinstance(stations, bool) or not isinstance(stations, (int, np.integer)) or stations < 2:
        raise ModelError(f"stations must be an integer >= 2 (points along each beam), got {stations!r}")
    if isinstance(exaggeration, bool) or not isinstance(exaggeration, (int, float)) or not 0 < exaggeration < 1e9:
        raise ModelError(f"exaggeration must be a factor > 0 on the beam deformation, got {exaggeration!r}")
    if type(model).__name__ == "SpatialModel":
        return _spatial_frames(model, result, rows)
    return _planar_frames(model, result, rows, int(stations), float(exaggeration))


def _limits(frames: list[Frame], dimension: int) -> np.ndarray:
    points = np.concatenate([np.concatenate(list(f.bodies.values()) + [f.joints]) for f in frames])[:, :dimension]
    low, high = points.min(axis=0), points.max(axis=0)
    centre, half = (low + high) / 2, max(float((high - low).max()) / 2 * 1.1, 1e-3)
    return np.array([centre - half, centre + half]).T


def animate(result: Any, path: str | os.PathLike, *, frames: int | None = 60, fps: float = 20.0,
            stations: int = 21, exaggeration: float = 1.0, dpi: int = 80, title: str | None = None) -> Path:
    """Write an animation of a planar or spatial run.

    Parameters
    ----------
    result : SimulationResult
        Of :func:`ctmm.simulate` on a planar / flexible / spatial model (see :func:`mechanism_frames`).
    path : str or os.PathLike
        Output file: ``.gif`` (matplotlib's Pillow writer, always available) or ``.mp4`` (needs the
        ``ffmpeg`` program; refused with a clear error when it is missing).
    frames : int or None
        Number of pictures, spread evenly over the stored rows (None: every row).
    fps : float
        Pictures per second of the file [1/s] (> 0).
    stations : int
        Points along each beam.
    exaggeration : float
        Factor on the beam deformation (shown in the title when not 1).
    dpi : int
        Resolution [dots per inch] (figure 5 x 5 in).
    title : str, optional
        Title above the time (default: the model name).

    Returns
    -------
    Path
        The written file (written to a temporary file in the target folder, then renamed into place).

    Raises
    ------
    ModelError
        Not a planar or spatial run, an unknown file ending, a missing folder, ``.mp4`` without ffmpeg,
        or a bad option (named with its value).
    """
    import matplotlib

    matplotlib.use("Agg") if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg") else None
    import matplotlib.pyplot as plt
    from matplotlib import animation as mpl_animation

    target = Path(path)
    suffix = target.suffix.lower()
    if suffix not in WRITERS:
        raise ModelError(f"path {str(target)!r}: an animation is written as one of {', '.join(WRITERS)}, "
                         f"got suffix {target.suffix!r}")
    if not target.parent.is_dir():
        raise ModelError(f"path {str(target)!r}: the folder {str(target.parent)!r} does not exist")
    if WRITERS[suffix] == "ffmpeg" and not mpl_animation.writers.is_available("ffmpeg"):
        raise ModelError(f"path {str(target)!r}: writing .mp4 needs the ffmpeg program, which is not installed "
                         "(install ffmpeg, e.g. apt-get install ffmpeg, or write a .gif)")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps < 1000:
        raise ModelError(f"fps must be a number of pictures per second in (0, 1000), got {fps!r}")
    if isinstance(dpi, bool) or not isinstance(dpi, (int, np.integer)) or not 10 <= dpi <= 1000:
        raise ModelError(f"dpi must be an integer resolution in [10, 1000] dots per inch, got {dpi!r}")
    model = _model(result)
    drawn = mechanism_frames(result, frame_rows(len(result.time), frames), stations=stations,
                             exaggeration=exaggeration)
    spatial = type(model).__name__ == "SpatialModel"
    figure = plt.figure(figsize=(5, 5), dpi=dpi)
    axes = figure.add_subplot(projection="3d") if spatial else figure.add_subplot()
    limits = _limits(drawn, 3 if spatial else 2)
    names = list(drawn[0].bodies)
    if spatial:
        axes.set(xlim=limits[0], ylim=limits[1], zlim=limits[2], xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")
        lines = [axes.plot([], [], [], "-", lw=3, color=f"C{i % 10}", label=n)[0] for i, n in enumerate(names)]
        dots = axes.plot([], [], [], "o", color="k", ms=5)[0]
    else:
        axes.set(xlim=limits[0], ylim=limits[1], xlabel="x [m]", ylabel="y [m]", aspect="equal")
        lines = [axes.plot([], [], "-", lw=3, color=f"C{i % 10}", label=n)[0] for i, n in enumerate(names)]
        dots = axes.plot([], [], "o", color="k", ms=5)[0]
        axes.grid(True, alpha=0.3)
    axes.legend(fontsize="x-small", loc="upper right")
    heading = title if title is not None else getattr(model, "name", "")
    heading += f"  (beam deformation x {exaggeration:g})" if exaggeration != 1 else ""

    def draw(k: int):
        frame = drawn[k]
        for line, name in zip(lines, names):
            points = frame.bodies[name]
            line.set_data(points[:, 0], points[:, 1])
            if spatial:
                line.set_3d_properties(points[:, 2])
        dots.set_data(frame.joints[:, 0], frame.joints[:, 1])
        if spatial:
            dots.set_3d_properties(frame.joints[:, 2])
        axes.set_title(f"{heading}  t = {frame.time:.3f} s")
        return [*lines, dots]

    # The writer grabs each picture with one savefig: one rendering per frame (FuncAnimation.save rendered every
    # frame twice, for the canvas's draw_idle after the update and for the grab).  The GIF keeps the figure's
    # colours as they are (Pillow takes transparency); an MP4 frame is opaque: the figure's face over white.
    red, green, blue, alpha = figure.get_facecolor()
    opaque = {} if suffix == ".gif" else {"facecolor": tuple(alpha * np.array([red, green, blue]) + 1 - alpha),
                                          "transparent": False}
    temporary = target.with_name(f".{target.stem}.{os.getpid()}.tmp{suffix}")
    try:
        writer = mpl_animation.PillowWriter(fps=fps) if suffix == ".gif" else mpl_animation.FFMpegWriter(fps=fps)
        with writer.saving(figure, temporary, dpi):
            for k in range(len(drawn)):
                draw(k)
                writer.grab_frame(**opaque)
        os.replace(temporary, target)
    finally:
        plt.close(figure)
        if temporary.exists():
            temporary.unlink()
    return target
