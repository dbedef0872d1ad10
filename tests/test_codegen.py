"""The one compile-and-cache helper (ctmm.codegen): cache hits and misses, keys, damaged entries, errors.

References: the loaded functions are checked against values computed by hand (integer arithmetic
and ``sin``), never against another compiled copy of the same code.
"""
from __future__ import annotations

import ctypes
import hashlib
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ctmm import codegen
from ctmm.errors import ModelError

SOURCE = "int twice(int x) { return 2 * x; }\n"
LIBM_SOURCE = "#include <math.h>\ndouble sine(double x) { return sin(x); }\n"


def _twice(path: Path) -> int:
    lib = ctypes.CDLL(str(path))
    lib.twice.argtypes, lib.twice.restype = [ctypes.c_int], ctypes.c_int
    return lib.twice(21)


def test_miss_then_hit(tmp_path):
    first = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    assert first.built and first.path.parent.parent == tmp_path / "kernels"
    assert _twice(first.path) == 42
    stat = first.path.stat()
    again = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    assert not again.built and again.path == first.path and again.key == first.key
    assert again.path.stat().st_mtime_ns == stat.st_mtime_ns and again.path.stat().st_ino == stat.st_ino
    # no temporary folders left behind
    assert sorted(p.name for p in (tmp_path / "kernels").iterdir()) == [first.path.parent.name]


def test_key_changes_with_source_and_flags(tmp_path, monkeypatch):
    monkeypatch.delenv(codegen.OPTIMIZATION_LEVEL_VARIABLE, raising=False)     # each build's own flags
    base = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    changed = codegen.shared_library(SOURCE + "/* changed */\n", "twice", cache_dir=tmp_path)
    flagged = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path, flags=("-O0", "-shared", "-fPIC"))
    assert changed.built and flagged.built
    assert len({base.key, changed.key, flagged.key}) == 3
    assert len({base.path, changed.path, flagged.path}) == 3


def test_damaged_entry_is_rebuilt(tmp_path):
    first = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    first.path.write_bytes(first.path.read_bytes()[:100])          # truncated library
    again = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    assert again.built and again.path == first.path
    assert _twice(again.path) == 42
    first.path.with_name(first.path.name + ".sha256").unlink()      # checksum lost
    assert codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path).built


def test_unloadable_entry_is_rebuilt_by_the_loader(tmp_path):
    entry = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    entry.path.write_bytes(b"not a shared library")                 # checksum made to agree
    entry.path.with_name(entry.path.name + ".sha256").write_text(hashlib.sha256(
        b"not a shared library").hexdigest())
    lib = codegen.load_ctypes(SOURCE, "twice", cache_dir=tmp_path)
    lib.twice.argtypes, lib.twice.restype = [ctypes.c_int], ctypes.c_int
    assert lib.twice(21) == 42 and codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path).built is False


def test_environment_variable_and_default_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path / "env"))
    assert codegen.shared_library(SOURCE, "twice").path.parent.parent == tmp_path / "env" / "kernels"
    monkeypatch.delenv("CTMM_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert codegen.cache_directory(subfolder="fmu") == tmp_path / "xdg" / "ctmm" / "fmu"


def test_load_ctypes_links_libm(tmp_path):
    lib = codegen.load_ctypes(LIBM_SOURCE, "sine", cache_dir=tmp_path)
    lib.sine.argtypes, lib.sine.restype = [ctypes.c_double], ctypes.c_double
    assert lib.sine(0.5) == math.sin(0.5)


def test_load_casadi(tmp_path):
    ca = pytest.importorskip("casadi")
    x = ca.SX.sym("x", 2)
    product = ca.Function("product", [x], [x[0] * x[1]])
    total = ca.Function("total", [x], [x[0] + x[1]])
    loaded = codegen.load_casadi([product, total], "pair", cache_dir=tmp_path)
    assert [f.name() for f in loaded] == ["product", "total"]
    assert float(loaded[0]([3.0, 7.0])) == 21.0 and float(loaded[1]([3.0, 7.0])) == 10.0


def test_compile_error_carries_the_compiler_message(tmp_path):
    with pytest.raises(ModelError, match=r"(?s)compiling 'broken'.*failed \(exit \d+\).*undeclared_name"):
        codegen.shared_library("int f(void) { return undeclared_name; }\n", "broken", cache_dir=tmp_path)
    assert not any((tmp_path / "kernels").iterdir())               # the failed build left nothing


def test_missing_compiler_and_bad_arguments(tmp_path):
    with pytest.raises(ModelError, match="compiler '/nonexistent/cc' not found"):
        codegen.shared_library(SOURCE, "twice", compiler="/nonexistent/cc", cache_dir=tmp_path)
    with pytest.raises(ModelError, match="name must be"):
        codegen.shared_library(SOURCE, "../escape", cache_dir=tmp_path)
    with pytest.raises(ModelError, match="source must be non-empty C text"):
        codegen.shared_library("  ", "twice", cache_dir=tmp_path)


def test_unwritable_cache_folder(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(ModelError, match=r"cache folder .*file/sub.* is not usable: cannot create it"):
        codegen.shared_library(SOURCE, "twice", cache_dir=blocker / "sub")
    monkeypatch.setenv("CTMM_CACHE", str(blocker))
    with pytest.raises(ModelError, match=r"\$CTMM_CACHE .* is not usable"):
        codegen.cache_directory()


def test_concurrent_builders_share_one_entry(tmp_path):
    script = ("import sys; from ctmm import codegen; "
              f"r = codegen.shared_library({SOURCE!r}, 'race', cache_dir=sys.argv[1]); print(r.path)")
    runs = [subprocess.Popen([sys.executable, "-c", script, str(tmp_path)], stdout=subprocess.PIPE, text=True)
            for _ in range(3)]
    paths = {run.communicate(timeout=120)[0].strip() for run in runs}
    assert all(run.returncode == 0 for run in runs)
    assert len(paths) == 1
    path = Path(paths.pop())
    assert codegen.shared_library(SOURCE, "race", cache_dir=tmp_path).built is False
    assert _twice(path) == 42
    assert [p.name for p in (tmp_path / "kernels").iterdir()] == [path.parent.name]


def test_losing_a_publish_race_uses_the_winner(tmp_path, monkeypatch):
    real = codegen.run_compiler
    winners = []

    def compile_then_lose(command, what):
        real(command, what)
        if not winners:                      # another builder publishes the entry meanwhile
            monkeypatch.setattr(codegen, "run_compiler", real)
            winners.append(codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path))

    monkeypatch.setattr(codegen, "run_compiler", compile_then_lose)
    loser = codegen.shared_library(SOURCE, "twice", cache_dir=tmp_path)
    assert winners[0].built and not loser.built and loser.path == winners[0].path
    assert _twice(loser.path) == 42
    assert [p.name for p in (tmp_path / "kernels").iterdir()] == [loser.path.parent.name]


def test_cache_key_frames_each_labelled_part():
    expected = hashlib.sha256(b"fmt/1" + b"source\0" + (3).to_bytes(8, "little") + b"abc"
                              + b"flags\0" + (0).to_bytes(8, "little")).hexdigest()
    assert codegen.cache_key(b"fmt/1", [("source", b"abc"), ("flags", b"")]) == expected
    # moving bytes between label and payload, or between parts, changes the key
    keys = {codegen.cache_key(b"fmt/1", parts) for parts in ([("ab", b"c")], [("a", b"bc")], [("a", b"b"), ("c", b"")])}
    assert len(keys) == 3
    assert codegen.cache_key(b"fmt/2", [("source", b"abc"), ("flags", b"")]) != expected


def _fake_compiler(path: Path, version: str) -> None:
    """A 'compiler' that prints ``version`` and counts its runs in ``<path>.runs``."""
    path.write_text(f"#!/bin/sh\necho run >> '{path}.runs'\necho '{version}'\n")
    path.chmod(0o755)


def _runs(path: Path) -> int:
    runs = Path(f"{path}.runs")
    return len(runs.read_text().splitlines()) if runs.exists() else 0


@pytest.mark.skipif(sys.platform == "win32", reason="a POSIX shell script stands for the compiler")
def test_compiler_identity_asks_the_compiler_once_per_file_state(tmp_path):
    compiler = tmp_path / "cc"
    _fake_compiler(compiler, "cc 1.0")
    first = codegen.compiler_identity(str(compiler))
    assert first == str(compiler.resolve()).encode() + b"\0cc 1.0\n"
    assert codegen.compiler_identity(str(compiler)) == first and _runs(compiler) == 1      # remembered
    _fake_compiler(compiler, "cc 2.0")                                 # replaced in place (size unchanged)
    stamp = compiler.stat().st_mtime_ns + 10 ** 9
    os.utime(compiler, ns=(stamp, stamp))
    assert codegen.compiler_identity(str(compiler)).endswith(b"\0cc 2.0\n") and _runs(compiler) == 2
    other = tmp_path / "cc-3"
    _fake_compiler(other, "cc 3.0.0")
    link = tmp_path / "gcc"
    link.symlink_to(compiler)
    assert codegen.compiler_identity(str(link)).endswith(b"\0cc 2.0\n")
    link.unlink()
    link.symlink_to(other)                                             # re-linked to another compiler
    assert codegen.compiler_identity(str(link)) == str(other.resolve()).encode() + b"\0cc 3.0.0\n"
    missing = str(tmp_path / "missing")
    assert codegen.compiler_identity(missing) == os.path.realpath(missing).encode() + b"\0"


def test_input_reads_go_through_one_pointer_per_input_and_zeros_for_an_absent_input(tmp_path):
    """casadi's ``arg[i]? arg[i][k] : 0`` reads are taken through one pointer per input
    (:func:`codegen.hoisted_input_reads`): the compiled function equals casadi's virtual machine, and called
    from C with an absent (NULL) input it reads zeros there, as the unchanged code does."""
    ca = pytest.importorskip("casadi")
    import numpy as np

    x, y = ca.SX.sym("x", 3), ca.SX.sym("y", 2)
    f = ca.Function("f", [x, y], [ca.vertcat(x[0] * y[1] + ca.sin(x[2]), x[1] - y[0] * y[1], ca.cos(y[0]))])
    source = codegen.casadi_source([f], "hoist")
    assert "? arg[0][" not in source and "? arg[1][" not in source and "ctmm_in1[1]" in source
    flags = ("-O0", "-shared", "-fPIC")
    (compiled,) = codegen.load_casadi([f], "hoist", cache_dir=tmp_path, flags=flags)
    xv, yv = [0.3, -1.2, 0.7], [2.0, 0.5]
    assert np.max(np.abs(np.asarray(compiled(xv, yv)) - np.asarray(f(xv, yv)))) <= 1e-15
    library = ctypes.CDLL(str(codegen.shared_library(source, "hoist", cache_dir=tmp_path, flags=flags).path))
    double_p = ctypes.POINTER(ctypes.c_double)
    x_in, out = (ctypes.c_double * 3)(*xv), (ctypes.c_double * 3)()
    arg, res = (double_p * 2)(ctypes.cast(x_in, double_p), None), (double_p * 1)(ctypes.cast(out, double_p))
    iw, w = (ctypes.c_longlong * 64)(), (ctypes.c_double * 64)()
    assert library.f(arg, res, iw, w, 0) == 0
    assert np.max(np.abs(np.array(out[:]) - np.asarray(f(xv, [0.0, 0.0])).ravel())) <= 1e-15
    assert np.array(out[:])[2] == 1.0


def test_a_time_loop_without_inputs_compiles_where_int_conversion_is_an_error(tmp_path):
    """A time loop whose step has empty inputs ``u`` and ``p`` (every kernel of a model without actuators or
    parameters): casadi writes ``casadi_copy(0, 0, 0+ i*0)`` for each empty column it repeats, an integer passed as a
    pointer, which GCC 14 refuses (``-Wint-conversion`` is an error there; ``-Werror=int-conversion`` gives the same
    here).  The copies of nothing are removed, so it compiles; the stride of two steps equals two steps of the
    oscillator ``x' = v, v' = -x`` worked by hand (semi-implicit Euler)."""
    ca = pytest.importorskip("casadi")
    import numpy as np

    from ctmm.generated_loop import time_loop_functions

    y, u, h, p, t0, k = (ca.MX.sym(label, rows) for label, rows in (("y", 2), ("u", 0), ("h", 1), ("p", 0),
                                                                    ("t0", 1), ("k", 1)))
    velocity = y[1] - h * y[0]
    step = ca.Function("step", [y, u, h, p, t0, k], [ca.vertcat(y[0] + h * velocity, velocity)])
    stride, _, blocks = time_loop_functions(step, 2, 4)
    assert "casadi_copy(0, 0, 0+" not in codegen.casadi_source([step, stride, *blocks], "no_inputs")
    flags = ("-O0", "-Werror=int-conversion", "-shared", "-fPIC")
    loaded = codegen.load_casadi([step, stride, *blocks], "no_inputs", cache_dir=tmp_path, flags=flags)
    state, dt = np.array([1.0, 0.0]), 0.1
    for _ in range(2):
        rate = state[1] - dt * state[0]
        state = np.array([state[0] + dt * rate, rate])
    compiled = np.asarray(loaded[1]([1.0, 0.0], ca.DM(0, 1), dt, ca.DM(0, 1), 0.0, 0.0)).ravel()
    assert np.max(np.abs(compiled - state)) <= 1e-15


def test_the_optimization_level_variable_replaces_every_o_flag_and_refuses_other_values(monkeypatch):
    """``$CTMM_OPTIMIZATION_LEVEL``: unset or empty, the flags as given; a level replaces every ``-O`` flag (put
    first when there is none); anything else is refused naming the variable, the value and the allowed ones."""
    variable = codegen.OPTIMIZATION_LEVEL_VARIABLE
    flags = ("-O2", "-shared", "-fPIC", "-Ofast")
    for unset in (None, "", "  "):
        if unset is None:
            monkeypatch.delenv(variable, raising=False)
        else:
            monkeypatch.setenv(variable, unset)
        assert codegen.effective_flags(flags) == list(flags)
    monkeypatch.setenv(variable, "0")
    assert codegen.effective_flags(flags) == ["-O0", "-shared", "-fPIC"]
    assert codegen.effective_flags(("-shared", "-fPIC")) == ["-O0", "-shared", "-fPIC"]
    monkeypatch.setenv(variable, "s")
    assert codegen.effective_flags(codegen.STRAIGHT_LINE_FLAGS) == ["-Os", "-shared", "-fPIC"]
    for bad in ("fast", "-O2", "4", "zero"):
        monkeypatch.setenv(variable, bad)
        with pytest.raises(ModelError, match=rf"CTMM_OPTIMIZATION_LEVEL = '{bad}'.*allowed: one of 0, 1, 2, 3, s, g"):
            codegen.effective_flags(flags)
        with pytest.raises(ModelError, match="CTMM_OPTIMIZATION_LEVEL"):
            codegen.shared_library(SOURCE, "twice", cache_dir="/nonexistent-never-reached")


def test_a_kernel_at_the_optimization_level_is_another_entry_with_the_same_numbers(tmp_path, monkeypatch):
    """One casadi function (20 RK4 steps of a damped pendulum with a cubic spring) compiled with its own
    ``-O2`` and at ``$CTMM_OPTIMIZATION_LEVEL=0``: two cache entries (the effective flags are in the key), both equal
    casadi's virtual machine to round-off."""
    ca = pytest.importorskip("casadi")
    import numpy as np

    x, h = ca.SX.sym("x", 2), ca.SX.sym("h")

    def rate(state):
        return ca.vertcat(state[1], -9.81 * ca.sin(state[0]) - 0.3 * state[1] - 4.0 * state[0] ** 3)

    state = x
    for _ in range(20):
        k1 = rate(state)
        k2 = rate(state + h / 2 * k1)
        k3 = rate(state + h / 2 * k2)
        k4 = rate(state + h * k3)
        state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    function = ca.Function("pendulum_rk4", [x, h], [state])
    start, step = [1.1, -0.4], 0.01
    reference = np.asarray(function(start, step)).ravel()
    results, folders = [], []
    for level in ("", "0"):
        monkeypatch.setenv(codegen.OPTIMIZATION_LEVEL_VARIABLE, level)
        (compiled,) = codegen.load_casadi([function], "pendulum_rk4", cache_dir=tmp_path)
        results.append(np.asarray(compiled(start, step)).ravel())
        folders.append(sorted(p.name for p in (tmp_path / "kernels").iterdir() if not p.name.startswith(".")))
    assert len(folders[0]) == 1 and len(folders[1]) == 2
    for result in results:
        assert np.max(np.abs(result - reference)) <= 1e-14 * np.max(np.abs(reference))


def test_selected_outputs_share_one_copy_of_the_terms_in_the_c_and_give_the_same_numbers():
    """Functions of outputs of one SX ``terms`` (a kinematic loop's rate and its cut loads) call it: the C text holds
    its expressions once (two SX functions of the same expressions held them twice), and the numbers are those of the
    SX functions on the same expressions."""
    import casadi as ca
    import numpy as np

    from ctmm.generated_loop import selected_outputs

    x, t = ca.SX.sym("x", 3), ca.SX.sym("t")
    shared = ca.sinh(ca.mtimes(x.T, x)) * x + t          # the expensive part, in both outputs
    terms = ca.Function("terms", [x, t], [shared[0] * 2.0, shared[1:] - t])
    rate, loads = selected_outputs(terms, [("rate", (0,)), ("loads", (1, 0))])
    separate = (ca.Function("rate", [x, t], [shared[0] * 2.0]), ca.Function("loads", [x, t], [shared[1:] - t,
                                                                                              shared[0] * 2.0]))
    assert codegen.casadi_source([rate, loads], "shared").count("sinh(") == 1
    assert codegen.casadi_source(list(separate), "separate").count("sinh(") == 2
    point = (np.array([0.3, -0.2, 0.5]), 0.7)
    assert [rate.name(), loads.name()] == ["rate", "loads"]
    assert float(rate(*point)) == float(separate[0](*point))
    for mine, theirs in zip(loads(*point), separate[1](*point)):
        np.testing.assert_array_equal(np.asarray(mine), np.asarray(theirs))


def test_input_reads_are_rewritten_only_as_whole_names_in_functions_starting_a_line():
    """:func:`codegen.hoisted_input_reads` rewrites ``arg[i]? arg[i][k] : 0`` as a whole name (not ``xarg[i]? ...``)
    in functions whose start begins a line; the rewritten text is worked by hand."""
    head = ("static int casadi_f{}(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, "
            "int mem) {{\n")
    text = ("x" + head.format(0) + "  b=arg[1]? arg[1][7] : 0;\n}\n"
            + head.format(1) + "  b=arg[3]? arg[3][12] : 0; c=xarg[0]? xarg[0][1] : 0; d=arg[0]? arg[0][0] : 0;\n}\n")
    assert codegen.hoisted_input_reads(text) == (
        "xstatic const casadi_real ctmm_zeros[13];\n" + head.format(0) + "  b=arg[1]? arg[1][7] : 0;\n}\n"
        + head.format(1) + "  const casadi_real *ctmm_in0 = arg[0] ? arg[0] : ctmm_zeros;\n"
        "  const casadi_real *ctmm_in3 = arg[3] ? arg[3] : ctmm_zeros;\n"
        "  b=ctmm_in3[12]; c=xarg[0]? xarg[0][1] : 0; d=ctmm_in0[0];\n}\n")


def test_a_small_mx_wrapper_is_inlined_into_the_time_loop_with_the_same_numbers(tmp_path, monkeypatch):
    """:func:`ctmm.generated_loop.inlined_call` inlines a step that only wraps calls (at most
    ``INLINED_INSTRUCTIONS``) into the time loop: fewer copies of the state per step in the generated C, the same
    numbers to the bit (and those of the steps worked by hand); an SX function and a larger graph stay calls."""
    ca = pytest.importorskip("casadi")
    import numpy as np

    from ctmm import generated_loop
    from ctmm.generated_loop import inlined_call, time_loop_functions

    n = 300
    x, t = ca.MX.sym("x", n), ca.MX.sym("t")
    inner = ca.Function("inner", [x, t], [0.5 * x + ca.sin(t)])
    y, u, h, p, t0, k = (ca.MX.sym(label, rows) for label, rows in (("y", n), ("u", 0), ("h", 1), ("p", 0),
                                                                    ("t0", 1), ("k", 1)))
    step = ca.Function("step", [y, u, h, p, t0, k], [inner(y, t0 + k * h)])
    flags = ("-O0", "-shared", "-fPIC")
    start = np.linspace(-1.0, 1.0, n)
    results, sources = [], []
    for limit in (0, generated_loop.INLINED_INSTRUCTIONS):
        monkeypatch.setattr(generated_loop, "INLINED_INSTRUCTIONS", limit)
        stride, _, blocks = time_loop_functions(step, 3, 2)
        source = codegen.casadi_source([step, stride, *blocks], f"wrapped{limit}")
        sources.append(source)
        loaded = codegen.load_casadi([step, stride, *blocks], f"wrapped{limit}", cache_dir=tmp_path, flags=flags)
        results.append(np.asarray(loaded[2](start, ca.DM(0, 1), 0.1, ca.DM(0, 1), 0.3, 2.0)))
    assert "= step(" in sources[0] and "= step(" not in sources[1]     # the fold calls inner, not step
    np.testing.assert_array_equal(results[1], results[0])
    assert np.max(np.abs(results[0][:, 0] - (0.5 ** 3 * start + 0.25 * np.sin(0.5) + 0.5 * np.sin(0.6)
                                               + np.sin(0.7)))) <= 1e-15
    symbol, other = ca.MX.sym("z", 2), ca.MX.sym("w", 2)          # called on other symbols (casadi inlines a
    expanded = ca.Function("expanded", [symbol], [2.0 * symbol]).expand()        # call on the function's own)
    assert "expanded" in str(inlined_call(expanded, [other]))
    large = ca.Function("large", [symbol], [sum((ca.sin(symbol * j) for j in range(40)), ca.MX.zeros(2))])
    assert large.n_instructions() > generated_loop.INLINED_INSTRUCTIONS
    assert "large" in str(inlined_call(large, [other]))
    assert "wrapper" not in str(inlined_call(ca.Function("wrapper", [symbol], [2.0 * symbol]), [other]))
