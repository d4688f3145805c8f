"""The PVG 32 rig as an FMU: the input voltage set by the importing tool moves the main spool as
pvgraph's own simulation does."""

import numpy as np
import pytest

from pvgraph.circuits.rig import build_rig
from pvgraph.simulate import simulate

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
from fmpy.validation import validate_fmu  # noqa: E402

from pvgraph.fmi import export_fmu  # noqa: E402

OUTPUTS = ["pvg.pvb.main_spool.flange.x", "load.f.port.p"]


@pytest.mark.slow
def test_rig_fmu_follows_a_voltage_step(tmp_path):
    path = export_fmu(build_rig(U_input=4.29), tmp_path / "rig.fmu", inputs=["U_input.k"],
                      outputs=OUTPUTS, rtol=1e-6)
    assert validate_fmu(path) == []
    inputs = np.array([(0.0, 4.29), (1.0, 4.29), (1.0, 4.6), (2.0, 4.6)],
                      dtype=[("time", float), ("U_input.k", float)])
    res = fmpy.simulate_fmu(path, stop_time=2.0, output_interval=0.1, input=inputs,
                            output=OUTPUTS)
    t = np.linspace(0.0, 2.0, 21)
    first = simulate(build_rig(U_input=4.29), 1.0, rtol=1e-6, t_eval=t[:11])
    second = simulate(build_rig(U_input=4.6).compile(), 2.0, t_start=1.0, rtol=1e-6,
                      t_eval=t[10:], y0=first.y[-1], yp0=first.yp[-1])
    for name, tol in zip(OUTPUTS, (2e-5, 0.2e5)):        # 0.02 mm, 0.2 bar
        expected = np.concatenate([first[name], second[name][1:]])
        assert np.max(np.abs(res[name] - expected)) < tol
    # nearer the neutral 5.75 V: less spool travel
    x = res["pvg.pvb.main_spool.flange.x"]
    assert x[10] < x[-1] < 0
