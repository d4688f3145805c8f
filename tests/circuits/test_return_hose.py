"""The rig's return hose between the L1/L3 junction and the Pb transducer, and its offset."""

import numpy as np
import pytest

from pvgraph.analysis import steady_state
from pvgraph.circuits import crossval as X
from pvgraph.circuits.pvg32.parameters import report_tuned
from pvgraph.circuits.rig import build_rig, laminar_load, readings
from pvgraph.circuits.scenarios import all_scenarios
from pvgraph.units import bar, lpm_per_bar, to_bar, to_lpm


def test_closed_l2_pm_minus_pb_is_a_flow_loss_plus_an_offset():
    """B.7: with L2 closed no flow passes L1, so Pm reads the L1/L3 junction. Over the 15
    closed-L2 points of both tables (taken on different occasions) Pm - Pb is a straight line
    in the load flow within the transducers' accuracy, and its zero-flow value is what the
    neutral points read directly."""
    closed = [s for s in all_scenarios() if not s.l2_open_finally]
    c0, c1, names = X._fit_measurement(closed)
    assert len(names) == 15
    for s in closed:
        line = c0 + c1 * to_lpm(s.measured.Q_total)
        assert abs(to_bar(s.measured.Pm - s.measured.Pb) - line) < 0.25, s.name
    neutral = [to_bar(s.measured.Pm - s.measured.Pb) for s in closed if s.measured.Q_total == 0]
    assert c0 == pytest.approx(np.mean(neutral), abs=0.05)
    # at zero flow Pf and Pm agree: the offset is Pb's (one transducer, not two)
    for s in closed:
        if s.measured.Q_total == 0:
            assert abs(to_bar(s.measured.Pf - s.measured.Pm)) < 0.1
    # a positive hose loss, larger than a bare 1 m of 12.7 mm hose (Hagen-Poiseuille, 0.0076
    # bar per L/min at 0.029 Pa s: B.6 hoses 5 and 8) but laminar-sized
    assert 0.0076 < c1 < 0.1
    # one flow level only: not identifiable
    assert X._fit_measurement([s for s in closed if s.measured.Q_total == 0]) is None


def test_hose_in_series_and_the_reading_offset():
    """With L2 closed the junction lies between L3 and the hose: Pm - Pb = Q / K_hose, and the
    Pb reading is the node pressure plus the transducer offset."""
    k_hose, offset = lpm_per_bar(23.0), bar(-0.475)
    p = report_tuned()
    p = p.model_copy(update={"rig": p.rig.model_copy(update={
        "return_hose_K": k_hose, "pb_sensor_offset": offset})})
    load = laminar_load(p, L1="large", L3="large", l2_open=False)
    op = steady_state(build_rig(p, load=load, U_input=4.29).compile(), tol=1e-10)
    q = op["load.L3.q"]
    pm, pb, pf = op["load.m.port.p"], op["load.b.port.p"], op["load.f.port.p"]
    assert pm - pb == pytest.approx(q / k_hose, rel=1e-6)
    assert q == pytest.approx(p.rig.L3.laminar_large * (pf - pm), rel=1e-6)
    assert op["load.return_hose.q"] == pytest.approx(q, rel=1e-9)
    r = readings(p, pf, pm, pb)
    assert (r["Pf"], r["Pm"], r["Pb"]) == (pf, pm, pb + offset)


def test_meter_out_edges_of_their_own_scale_the_return_drop():
    """main_spool.meter_out_area_ratio = (r0, 0) multiplies the return edge's area by r0: the
    orifice law (eq. 4.84) then gives the meter-out drop Pb - P_T at a given flow 1/r0^2 times
    the drop with the report's one A_H; the meter-in side (flow within 2 %) is untouched."""
    p0 = report_tuned()
    p2 = p0.model_copy(update={"main_spool": p0.main_spool.model_copy(
        update={"meter_out_area_ratio": (2.0, 0.0)})})
    per_q2 = []
    flows = []
    for p in (p0, p2):
        system = build_rig(p, load=laminar_load(p, L3="large"), U_input=4.45).compile()
        op = steady_state(system, tol=1e-10)
        q = op["load.L3.q"]
        per_q2.append((op["load.b.port.p"] - op["pvg.T.p"]) / q**2)
        flows.append(q)
    assert per_q2[1] / per_q2[0] == pytest.approx(0.25, rel=0.01)
    assert flows[1] == pytest.approx(flows[0], rel=0.02)
