"""The generated RK4 time loop of any scene: one step, strides of steps, blocks of strides (issue 13).

A scene that states its rates on casadi symbols -- ``y_dot = rate(y, u, p, t)`` as a
``casadi.Function`` (:class:`SymbolicRates`) -- compiles through this module without it knowing the
scene's family: :class:`ctmm.compiled_scene.CompiledScene` (planar models, the one articulated sweep
at ``d = 3``) and :class:`ctmm.compiled_spatial.CompiledSpatialScene` (spatial models, ``d = 6``,
quaternion coordinates) both build their kernels here.

Generated functions (all with the inputs ``y, u, h, p, t0, k``: state, held actuator inputs, step
[s], parameters, start time [s] and the index of the first step, a double):

* ``step`` -- RK4 step ``k`` from ``t0 + k h``: :func:`ctmm.ode.rk4_step` run on symbols (the one
  scheme statement);
* ``stride`` -- ``store_every`` steps (``fold``);
* ``block<size>`` -- ``size`` strides with every stored state returned, for
  ``size = rows, rows/2, rows/4, ... > 1`` (the smallest a ``mapaccum`` of strides, each larger
  one two calls of the next smaller and, for an odd size, a stride: building them costs little
  whatever the rate), so a whole interval runs inside the generated C with one
  call per block and a remainder costs one call per binary digit.

:func:`run_blocks` runs them over an interval (and a batch of members through
``casadi.Function.map``); a run of many short intervals (co-simulated controllers end one at each sample) passes
the run's :class:`BlockRunner`, which sets each function's call buffer up once.  :func:`compiled_time_loop` compiles them (every generated-kernel path goes
through it): the cache key is computed from the serialized step before the blocks and the C text are
built, so a call whose library is cached builds and generates nothing; or, where a family describes
everything its builder reads (``description``: the model and options by
:func:`ctmm.model_description.describe`, with the package's code), before the step itself is built, so a
cached call builds no symbol at all (spatial scenes and controlled spatial kernels with their numbers as
constants, the DT-TMM schemes of chains; planar scenes and the chains' RK4, and models holding Python
callables or foreign objects, keep the built step's key).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, Sequence

import numpy as np

from .codegen import load_casadi_keyed
from .version import __version__

from .ode import rk4_step

__all__ = ["INLINED_INSTRUCTIONS", "SymbolicRates", "TimeLoop", "block_sizes", "compiled_time_loop", "inlined_call",
           "rk4_step_function", "selected_outputs", "time_loop_functions", "run_blocks", "BlockRunner"]

_LOOP_CODE = Path(__file__).read_bytes()        # this module builds stride and blocks: part of every key


class SymbolicRates(Protocol):
    """What a scene supplies to be compiled: its rates on casadi symbols.

    Attributes
    ----------
    rate : casadi.Function
        ``y_dot = rate(y, u, p, t)``: state ``y`` (``state_size``), held inputs ``u``, parameters
        ``p``, time ``t`` [s].
    """

    rate: Any


def rk4_step_function(rate: Any) -> Any:
    """The generated ``step(y, u, h, p, t0, k)``: one RK4 step of ``rate`` (a ``casadi.Function``
    ``(y, u, p, t) -> y_dot``) from ``t0 + k h`` by ``h`` with ``u`` and ``p`` held.

    On MX symbols the rate stays one C function called by the four stages (an SX call would inline it).
    """
    import casadi as ca

    y, u, p = (ca.MX.sym(label, *rate.size_in(i)) for i, label in ((0, "y"), (1, "u"), (2, "p")))
    h, t0, k = ca.MX.sym("h"), ca.MX.sym("t0"), ca.MX.sym("k")
    return ca.Function("step", [y, u, h, p, t0, k],
                       [rk4_step(lambda stage, state: rate(state, u, p, stage), t0 + k * h, y, h)])


def selected_outputs(terms: Any, selections: Sequence[tuple[str, Sequence[int]]]) -> list[Any]:
    """Functions ``name(*inputs of terms) -> (outputs of terms at indices)``, one per ``(name, indices)`` of
    ``selections``, each one call of ``terms`` on MX symbols: the generated C holds ``terms`` once, called by each,
    where functions of the same expressions on SX symbols would each hold their own copy of them (a kinematic loop's
    RK4 rate and its stored cut loads: two copies of the sweep with the cut forces, ~28 % of the C and of gcc's time).
    The numbers are those of the separate functions (the same operations).

    Parameters
    ----------
    terms : casadi.Function
        The shared expressions (an SX function: straight-line code).
    selections : sequence of (str, sequence of int)
        Name of each function and the indices of ``terms``'s outputs it returns, in that order.
    """
    import casadi as ca

    inputs = [ca.MX.sym(terms.name_in(i), terms.sparsity_in(i)) for i in range(terms.n_in())]
    results = terms.call(inputs)
    return [ca.Function(name, inputs, [results[i] for i in indices]) for name, indices in selections]


def block_sizes(rows: int) -> list[int]:
    """Strides per block of :func:`time_loop_functions`: ``rows, rows/2, rows/4, ... > 1`` (integer halves)."""
    return [rows >> j for j in range(rows.bit_length()) if rows >> j > 1]


@dataclass(frozen=True)
class TimeLoop:
    """The compiled functions of :func:`compiled_time_loop`.

    Attributes
    ----------
    extra : tuple
        The compiled ``extra`` functions, in the order given.
    step, stride : casadi.Function
        The compiled step and stride (:func:`time_loop_functions`).
    blocks : list of (int, casadi.Function)
        ``(size, block)`` for the sizes of :func:`block_sizes`, largest first (for :func:`run_blocks`).
    """

    extra: tuple
    step: Any
    stride: Any
    blocks: list


def compiled_time_loop(step: Any, store_every: int, rows: int, name: str, *, extra: Sequence[Any] = (),
                       description: Sequence[tuple[str, bytes]] | None = None, **options: Any) -> TimeLoop:
    """The compiled ``step``, stride, blocks (:func:`time_loop_functions`) and ``extra`` functions of one
    library, from the kernel cache when it holds them (nothing but the key computed) or built now.

    The cache key (:func:`ctmm.codegen.load_casadi_keyed`) is computed before the time loop's graph
    and the C text, from ``store_every``, ``rows``, the text of this module (which builds the rest from
    the step), the ctmm version (codegen adds the casadi version, compiler and flags) and either

    * the serialized ``step`` and ``extra`` functions (every number and the structure of the model,
      options, the loops), which the caller built for it; or
    * with ``description``: the caller's complete description of what its builder reads (the model and
      options, :func:`ctmm.model_description.describe`), the text of every module of the package
      (:func:`ctmm.model_description.package_digest`: the code that reads them), the Python, numpy and
      scipy versions -- computed without building anything, so a cached call builds no symbols at all.

    Parameters
    ----------
    step : casadi.Function or callable
        The generated ``step(y, u, h, p, t0, k)``; with ``description``, a builder ``() -> (step, extra)``
        called only when the library is not cached.
    store_every, rows : int
        As in :func:`time_loop_functions`.
    name : str
        Library name (:func:`ctmm.codegen.shared_library`).
    extra : sequence of casadi.Function, optional
        Further functions of the same library (an acceleration, an unguarded step), named apart from
        ``step``, ``stride`` and ``block<size>`` (with ``description``: the builder returns them).
    description : sequence of (str, bytes), optional
        Labelled parts that determine everything the builder generates (the caller's responsibility:
        give it only when complete; else leave it out and pass the built step).
    **options
        ``flags``, ``compiler``, ``cache_dir`` of :func:`ctmm.codegen.shared_library`.
    """
    sizes = block_sizes(rows)
    parts = [("ctmm", __version__.encode()), ("time loop", _LOOP_CODE),
             ("store_every", str(int(store_every)).encode()), ("rows", str(int(rows)).encode())]
    if description is not None:
        import scipy

        from .model_description import PACKAGE_DIGEST

        parts += [("package", PACKAGE_DIGEST), ("python", sys.version.encode()),
                  ("numpy", np.__version__.encode()), ("scipy", scipy.__version__.encode()), *description]
        def build_described() -> list[Any]:
            function, more = step()
            stride, _, blocks = time_loop_functions(function, store_every, rows)
            return [*more, function, stride, *blocks]

        loaded = load_casadi_keyed(parts, None, build_described, name, **options)
        count = len(loaded) - 2 - len(sizes)
        return TimeLoop(tuple(loaded[:count]), loaded[count], loaded[count + 1], list(zip(sizes, loaded[count + 2:])))
    names = [function.name() for function in (*extra, step)] + ["stride"] + [f"block{size}" for size in sizes]
    functions = [*extra, step]
    parts += [(f"function {function.name()}", function.serialize().encode()) for function in functions]

    def build() -> list[Any]:
        stride, _, blocks = time_loop_functions(step, store_every, rows)
        return [*extra, step, stride, *blocks]

    loaded = load_casadi_keyed(parts, names, build, name, **options)
    count = len(extra)
    return TimeLoop(tuple(loaded[:count]), loaded[count], loaded[count + 1], list(zip(sizes, loaded[count + 2:])))


def time_loop_functions(step: Any, store_every: int, rows: int) -> tuple[Any, list[int], list[Any]]:
    """``(stride, sizes, blocks)`` of a generated ``step(y, u, h, p, t0, k)``: ``stride`` runs
    ``store_every`` steps, ``blocks[i]`` runs ``sizes[i]`` strides and returns every stored state
    (columns), ``sizes = rows, rows/2, ... > 1``.

    The graph is built on the inputs that hold numbers only (an empty ``u`` or ``p``: no actuators, numbers as
    constants, left out of the inner functions; the exported ones take all six and call them): casadi checks every
    symbolic call with an empty (so all-zero) argument for outputs it would make zero, a sweep through the called
    graph with every nested call expanded, which made each block's call cost as much as all its steps (1.3-2.9 s of a
    100-body spatial chain's first compile).  The same operations in the same order: the numbers are unchanged."""
    import casadi as ca

    y, u, h, p, t0, k = (ca.MX.sym(label, *step.size_in(i)) for i, label in enumerate(("y", "u", "h", "p", "t0", "k")))
    arguments = [y, u, h, p, t0, k]
    kept = [index for index, symbol in enumerate(arguments) if symbol.numel() > 0]
    dropped = len(kept) < len(arguments)

    def inner(name: str, output: Any) -> Any:
        return ca.Function(f"{name}_kept" if dropped else name, [arguments[index] for index in kept], [output])

    def exported(name: str, function: Any) -> Any:
        return ca.Function(name, arguments, [call(function, arguments)]) if dropped else function

    def call(function: Any, values: Sequence[Any]) -> Any:
        return function(*[values[index] for index in kept])

    def repeated(count: int, first: Any) -> list:
        return [y] + [ca.repmat(x, 1, count) for x in (u, h, p, t0)] + [first]

    one = inner("step", inlined_call(step, arguments)) if dropped else step
    stride_kept = inner("stride", call(one.fold(store_every), repeated(
        store_every, k + ca.DM(np.arange(store_every, dtype=float)).T)) if store_every > 1 else call(one, arguments))
    sizes = block_sizes(rows)
    kept_blocks: list = []
    for size in reversed(sizes):                # ascending: each block two calls of the one before
        if not kept_blocks or size // 2 != sizes[len(sizes) - len(kept_blocks)]:
            first = k + ca.DM(store_every * np.arange(size, dtype=float)).T
            output = call(stride_kept.mapaccum(f"block{size}_acc", size), repeated(size, first))
        else:
            half, count = kept_blocks[-1], size // 2
            head = call(half, arguments)
            parts = [head, call(half, [head[:, -1], u, h, p, t0, k + store_every * count])]
            if size % 2:                        # an odd size: one stride more
                parts.append(call(stride_kept, [parts[-1][:, -1], u, h, p, t0, k + store_every * (size - 1)]))
            output = ca.horzcat(*parts)
        kept_blocks.append(inner(f"block{size}", output))
    stride = exported("stride", stride_kept)
    blocks = [exported(f"block{size}", block) for size, block in zip(reversed(sizes), kept_blocks)]
    blocks.reverse()
    return stride, sizes, blocks


class BlockRunner:
    """Reusable call buffers of :func:`run_blocks` for the intervals of one run (one ``ctmm.simulate`` call).

    A co-simulated controller ends the generated interval at each sample, so a run calls :func:`run_blocks` once
    per sample interval, often for a few steps only.  Setting up a casadi buffer (``Function.buffer()``, every
    input bound: about 15 us CPU per function) then costs as much as the steps; a runner sets each compiled
    function up once (per batch size) and afterwards only copies the interval's state, inputs and start index into
    the bound arrays.  Create one per run and pass it to every :func:`run_blocks` call of that run (not shared
    between threads); the answers are those of a call without it, bit for bit (the same generated functions on the
    same numbers).

    Attributes
    ----------
    calls : dict
        ``(function id, batch, parallelization, threads) -> (function, buffered call)``, filled at first use.
    """

    def __init__(self) -> None:
        self.calls: dict[tuple, tuple[Any, Any]] = {}

    def bound(self, function: Any, batch: int, parallelization: str, threads: int,
              fixed: Sequence[np.ndarray]) -> Any:
        """``call(y, k, shape)`` of :func:`run_blocks` for ``function`` (mapped over ``batch`` members) with the
        ``fixed`` ``(u, h, p, t0)`` of this interval: set up at its first use, its inputs rewritten after."""
        key = (id(function), batch, parallelization, threads)
        entry = self.calls.get(key)
        if entry is None or entry[0] is not function:
            mapped = function if batch == 1 else function.map(batch, parallelization, threads)
            entry = (function, _BufferedFunction(mapped))
            self.calls[key] = entry
        entry[1].fix(fixed)
        return entry[1].call


def run_blocks(blocks: list[tuple[int, Any]], stride: Any, step: Any, store_every: int, y: np.ndarray,
               u: np.ndarray, h: float, n_steps: int, t0: float, p: np.ndarray, parallelization: str = "serial",
               threads: int = 1, first_step: int = 0, runner: BlockRunner | None = None) -> np.ndarray:
    """Stored states (B, rows, state size) after each ``store_every`` steps and after the last step of
    ``n_steps`` RK4 steps of ``h`` [s] from ``t0`` [s], for the B members (columns of ``y`` (state size,
    B) and ``p``); compiled ``blocks`` ``[(size, function)]``, ``stride`` and ``step`` of
    :func:`time_loop_functions`, mapped over the batch by ``casadi.Function.map`` (nothing generated
    or compiled); stops after the first block where every member holds a non-finite state.  ``first_step``:
    the index of the first step (steps at ``t0 + k h``, ``k`` from it: a run continued from a stored state).
    ``runner``: the run's :class:`BlockRunner` (its buffers reused over the run's intervals; default a new one)."""
    every, batch = store_every, y.shape[1]
    strides, rest = divmod(n_steps, every)
    size_y = y.shape[0]
    runner = BlockRunner() if runner is None else runner

    fixed = (np.asarray(u, float), np.asarray(h, float), np.asarray(p, float), np.asarray(t0, float))
    out = []
    done = 0
    for size, function in blocks if strides > 1 else ():   # (the smallest block has two strides)
        if done + size > strides:
            continue
        call = runner.bound(function, batch, parallelization, threads, fixed)
        while done + size <= strides:
            block = call(y, first_step + done * every, (batch, size, size_y))      # (B, size, n)
            out.append(block)
            y = block[:, -1, :].T
            done += size
            if not np.any(np.all(np.isfinite(block), axis=(1, 2))):
                return np.concatenate(out, axis=1)
    if done < strides:
        call = runner.bound(stride, batch, parallelization, threads, fixed)
        for j in range(done, strides):
            y = call(y, first_step + j * every, (batch, size_y)).T
            out.append(y.T[:, None, :])
    if rest:
        call = runner.bound(step, batch, parallelization, threads, fixed)
        for j in range(rest):
            y = call(y, first_step + strides * every + j, (batch, size_y)).T
        out.append(y.T[:, None, :])
    if len(out) == 1:
        return out[0]
    return np.concatenate(out, axis=1) if out else np.zeros((batch, 0, y.shape[0]))


class _BufferedFunction:
    """``function(y, u, h, p, t0, k)`` through casadi's buffer interface, its inputs bound once to arrays held here.

    No conversion through Python numbers (a casadi ``DM`` result costs about 25 ns per number to convert, more
    than a generated step of a chain spends per point).  The buffer holds pointers to the input arrays: this
    object keeps every one of them alive and only rewrites their contents.  An input given for one member (columns
    of ``y`` are members) is repeated over a mapped function's members."""

    def __init__(self, function: Any) -> None:
        self.function = function
        self.buffer, self.evaluate = function.buffer()
        self.arrays = [np.zeros(function.nnz_in(index)) for index in range(6)]
        for index, array in enumerate(self.arrays):
            self.buffer.set_arg(index, memoryview(array))
        self.output = np.zeros(function.nnz_out(0))         # bound once; each call returns a copy of it
        self.buffer.set_res(0, memoryview(self.output))

    def fix(self, fixed: Sequence[np.ndarray]) -> None:
        """Write the ``(u, h, p, t0)`` (float arrays) of an interval into the bound input arrays (an empty one
        stays zero)."""
        for array, value in zip(self.arrays[1:5], fixed):
            data = value.ravel(order="F")                       # column-major (a view where it can be)
            if data.size == array.size:
                array[:] = data
            elif data.size:
                array[:] = np.tile(data, array.size // data.size)

    def call(self, y: np.ndarray, k: int, shape: tuple) -> np.ndarray:
        """The output for the state ``y`` from step ``k`` into a new C-ordered array of ``shape`` (the output's
        column-major data: a ``(rows, columns)`` output is ``(columns, rows)``)."""
        arrays = self.arrays
        y = np.asarray(y, float)
        np.copyto(arrays[0].reshape(y.shape[::-1]), y.T)      # column-major data of y (state size, members)
        arrays[5][:] = k
        self.evaluate()
        if self.buffer.ret():
            raise RuntimeError(f"the generated function {self.function.name()!r} failed (status {self.buffer.ret()})")
        return self.output.reshape(shape).copy()


INLINED_INSTRUCTIONS = 64
"""Largest MX graph (instructions) that :func:`inlined_call` inlines into its caller: a wrapper around calls."""


def inlined_call(function: Any, arguments: Sequence[Any]) -> Any:
    """``function(*arguments)`` (its one output) with the function's graph inlined into the caller's when it is an
    MX function of at most :data:`INLINED_INSTRUCTIONS` instructions (``Function.call(..., always_inline=True)``),
    else a call.  The same operations on the same numbers.  In generated C each nested call writes its output to a
    work vector that the caller then copies into its own: a 1000-mass chain's Newmark step (a wrapper of a wrapper
    of its node loops, nested in the time loop) copied its 5000 numbers three times per step, 11.7 -> 8.2 us per
    step with the wrappers inlined.  A larger graph stays a call (its code once in the library)."""
    if function.is_a("MXFunction") and function.n_instructions() <= INLINED_INSTRUCTIONS:
        return function.call(list(arguments), True, False)[0]
    return function(*arguments)
