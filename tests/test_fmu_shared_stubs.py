"""The stubs of the FMI calls no ctmm FMU supports are one C source per FMI version
(``controllers/fmu_common``), linked into the shipped controller FMUs' sources and copied into every
exported plant FMU; each FMU's main source defines the logger the stubs call."""
from __future__ import annotations

from pathlib import Path

import pytest

from ctmm.fmu_export_files import UNSUPPORTED_FILES, unsupported_source

COMMON = Path(__file__).resolve().parents[1] / "controllers" / "fmu_common"
USERS = {"2": ("pd_controller", "pi_controller", "lag_filter_me"), "3": ("pd_controller_fmi3", "typed_io_fmi3")}


@pytest.mark.parametrize("major", ["2", "3"])
def test_controllers_and_exports_share_one_stub_source(major):
    name = UNSUPPORTED_FILES[major]
    shared = COMMON / name
    assert unsupported_source(f"{major}.0") == (name, shared.read_text())
    for fmu in USERS[major]:
        sources = COMMON.parent / "fmu" / fmu / "sources"
        assert (sources / name).resolve() == shared.resolve()
        main = "".join(path.read_text() for path in sources.glob("*.c") if path.name != name)
        assert f"ctmm_fmi{major}_not_supported(" in main            # the logger the stubs call
        stubbed = [line.split("(")[0].split()[-1] for line in shared.read_text().splitlines()
                   if line.startswith(f"fmi{major}Status fmi{major}")]
        assert stubbed and not any(f"Status {function}(" in main for function in stubbed)   # defined once
