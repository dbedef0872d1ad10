"""FMI 2 logging through fmpy's process-wide formatting proxy cannot crash the process.

Each scenario runs in a fresh Python subprocess, so a segmentation fault fails the test instead of
killing pytest.  The independent evidence is the operating system's exit status and the text the
FMU printed or logged (the messages are written by the exported FMU's C code).
"""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import ctmm
from ctmm.planar import Fixed, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.control.fmu import build_fmu

from _controllers_import import load_controllers

WRONG_STEP = "not a whole multiple of the FMU's step 0.001"


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("logging_fmus")
    pendulum = PlanarModel.chain("swing", [Fixed("ground"), SpringDamperHinge("pivot", stiffness=2.0, damping=0.1),
                                           RigidBody.uniform_link("rod", mass=1.0, length=0.8)])
    plant = ctmm.export_fmu(pendulum, folder / "swing.fmu", step=1e-3, q0=np.array([0.1]), qdot0=np.array([0.0]),
                            outputs=["rod.theta"])
    controller = build_fmu(load_controllers().fmu_source("pd_controller"), folder / "pd", compiler="gcc")
    return {"plant": str(plant), "controller": str(controller)}


def run_script(body: str, **paths: str) -> subprocess.CompletedProcess:
    script = textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", script, *paths.values()], capture_output=True, text=True,
                          timeout=120)


START_PLANT = """
import sys, fmpy
from fmpy.fmi2 import FMU2Slave

def start_plant(path, name, callbacks=None):
    description = fmpy.read_model_description(path)
    plant = FMU2Slave(guid=description.guid, unzipDirectory=fmpy.extract(path),
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    plant.instantiate(callbacks=callbacks)
    plant.setupExperiment(startTime=0.0)
    plant.enterInitializationMode()
    plant.exitInitializationMode()
    return plant

def refused_step(plant):
    try:
        plant.doStep(0.0, 1.5e-3)
    except Exception as exc:
        return str(exc)
    raise SystemExit("the FMU accepted a step that is not a multiple of its own step")
"""


def test_an_fmu_with_default_callbacks_logs_after_a_closed_fmu_controller(fmus):
    """The reported crash: a closed FMUController state (FMI 2) freed its logger; fmpy's default
    callbacks then logged through the stale global pointer."""
    result = run_script(START_PLANT + """
import gc
import numpy as np
from ctmm.control.fmu import FMUController
controller = FMUController(sys.argv[2], inputs={"y": "m6.x", "ydot": "m6.v"}, outputs={"u": "m2.force"},
                           sample_time=0.01)
with controller.init(0.0) as state:
    controller.step(0.0, np.array([0.25, 0.0]), state)
del state, controller
gc.collect()
plant = start_plant(sys.argv[1], "default")   # fmpy's default callbacks
print("refused:", refused_step(plant), flush=True)
plant.freeInstance()
print("alive", flush=True)
""", plant=fmus["plant"], controller=fmus["controller"])
    assert result.returncode == 0, (result.returncode, result.stdout, result.stderr)
    assert "alive" in result.stdout
    assert f"[ERROR] " in result.stdout and WRONG_STEP in result.stdout   # printed by fmpy's default logger path


def test_each_instance_keeps_its_own_messages_and_freed_callbacks_are_harmless(fmus):
    """Two live instances with ctmm callbacks log into their own logs, not the last one created; after
    both callbacks are freed, fmpy.simulate_fmu on a failing FMU reports the error instead of crashing."""
    result = run_script(START_PLANT + """
import collections, gc
from ctmm.control.fmu_calls import fmi2_callbacks
logs = [collections.deque(), collections.deque()]
plants = [start_plant(sys.argv[1], name, fmi2_callbacks(log)) for name, log in zip(("first", "second"), logs)]
refused_step(plants[0])
assert len(logs[0]) == 1 and "not a whole multiple" in logs[0][0] and not logs[1], (logs, "first")
plants[1].doStep(0.0, 1e-3)
refused_step(plants[1])
assert len(logs[0]) == 1 and len(logs[1]) == 1 and "is not the FMU's time" in logs[1][0], (logs, "second")
for plant in plants:
    plant.freeInstance()
    plant.callbacks = None
del plants
gc.collect()
try:
    fmpy.simulate_fmu(sys.argv[1], stop_time=0.01, output_interval=1.5e-3, step_size=1.5e-3)
except Exception as exc:
    print("simulate_fmu refused:", exc, flush=True)
print("alive", flush=True)
""", plant=fmus["plant"])
    assert result.returncode == 0, (result.returncode, result.stdout, result.stderr)
    assert "alive" in result.stdout and "simulate_fmu refused" in result.stdout
    assert WRONG_STEP in result.stdout
