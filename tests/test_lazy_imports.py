"""Building a model pays only for what it uses: a chain with a feedback loop of plain-number gains does not import
python-control (~1.5 s of CPU on first import); an LTI gain, which needs python-control to exist, is still
recognised.  Run in a fresh interpreter (the test session has imported python-control already)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    import ctmm
    from ctmm.elements import Fixed, SpringDamper, Mass, Free
    from ctmm.control import Feedback, ControlledChain

    plant = ctmm.Chain("c", [Fixed("wall"), SpringDamper("K1", 1000.0, 0.5), Mass("m2", 1.0),
                             SpringDamper("K3", 1000.0, 0.5), Mass("m4", 1.0), Free("end")])
    loop = Feedback("Ka", sensor="m4.v", actuator="m2", gain=2.0, delay=0.005)
    system = ControlledChain(plant, [loop])
    s = np.array([1j, 10j])
    gain = loop.loop_gain(s)
    assert not loop.is_lti and np.allclose(gain, 2.0 * np.exp(-s * 0.005))
    print("control imported:", "control" in sys.modules)
    import control
    lead = Feedback("lead", sensor="m4.v", actuator="m2", gain=control.tf([2.0, 1.0], [0.1, 1.0]))
    ControlledChain(plant, [lead])
    assert lead.is_lti and np.allclose(lead.controller_response(s), (2.0 * s + 1.0) / (0.1 * s + 1.0))
    print("lti recognised")
""")


def test_a_number_gain_loop_does_not_import_python_control_and_an_lti_gain_is_still_recognised():
    completed = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300)
    assert completed.returncode == 0, completed.stderr
    assert "control imported: False" in completed.stdout, completed.stdout
    assert "lti recognised" in completed.stdout
