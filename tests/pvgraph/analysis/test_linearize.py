"""Linear models: exact for linear circuits, analytic poles, margins, the PVG 32 example."""

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from components import (Constant, Damper, FlowSource, ForceInput, LaminarOrifice, LinearSpring,
                        SpoolMass, Tank, VolumeNode)
from pvgraph import Circuit
from pvgraph.analysis import linearize_circuit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_compiler import BETA, K, Q, V  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]


def laminar(u):
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=u["Q"]))
    node = c.add("node", VolumeNode(V=V))
    orf = c.add("orifice", LaminarOrifice(K=K))
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, c.add("tank", Tank()).port)
    return c


def test_linear_circuit_is_exact():
    lm = linearize_circuit(laminar, {"Q": Q}, ["node.port.p", "orifice.a.q", "tank.port.p"])
    assert lm.state_names == ["node.port.p"]
    assert lm.A[0, 0] == pytest.approx(-BETA * K / V, rel=1e-9)
    assert lm.B[0, 0] == pytest.approx(BETA / V, rel=1e-9)
    assert lm.C[0, 0] == 1.0 and lm.D[0, 0] == 0.0
    assert lm.C[1, 0] == pytest.approx(K, rel=1e-12)        # orifice flow K p
    assert np.all(lm.C[2] == 0.0) and np.all(lm.D[2] == 0.0)  # fixed tank pressure
    assert lm.dc_gain()[0, 0] == pytest.approx(1.0 / K, rel=1e-9)
    num, den = lm.tf("node.port.p", "Q")
    assert num[-1] / den[-1] == pytest.approx(1.0 / K, rel=1e-9)


M, KS, D = 2.0, 5.0e3, 40.0


def smd(u):
    c = Circuit("smd")
    mass = c.add("mass", SpoolMass(m=M))
    spring = c.add("spring", LinearSpring(k=KS))
    damper = c.add("damper", Damper(d=D))
    force = c.add("force", ForceInput())
    c.connect(mass.flange, spring.flange, damper.flange, force.flange)
    c.connect(c.add("F", Constant(k=u["F"])).y, force.u)
    return c


def test_spring_mass_damper_poles():
    lm = linearize_circuit(smd, {"F": 10.0}, ["mass.flange.x", "spring.flange.f"])
    assert lm.op["mass.flange.x"] == pytest.approx(10.0 / KS, rel=1e-9)
    exact = np.sort_complex(np.roots([M, D, KS]))
    assert np.allclose(np.sort_complex(lm.poles()), exact, rtol=1e-9)
    assert lm.dc_gain()[0, 0] == pytest.approx(1.0 / KS, rel=1e-9)
    assert lm.dc_gain()[1, 0] == pytest.approx(1.0, rel=1e-9)  # the spring takes the force
    ss = lm.to_control()
    import control
    assert np.allclose(np.sort_complex(control.poles(ss)), exact, rtol=1e-9)


def test_margins_with_python_control():
    import control
    G = control.tf([1.0], [1.0, 3.0, 2.0, 0.0])  # 1 / (s (s+1) (s+2))
    gm, pm, wcg, wcp = control.margin(G)
    assert gm == pytest.approx(6.0, rel=1e-6)          # |G(j sqrt 2)| = 1/6
    assert wcg == pytest.approx(math.sqrt(2.0), rel=1e-6)
    w2 = [r.real for r in np.roots([1.0, 5.0, 4.0, -1.0]) if abs(r.imag) < 1e-12 and r.real > 0]
    w = math.sqrt(w2[0])                                # w^2 (w^2+1)(w^2+4) = 1
    pm_hand = 90.0 - math.degrees(math.atan(w) + math.atan(w / 2.0))
    assert wcp == pytest.approx(w, rel=1e-6)
    assert pm == pytest.approx(pm_hand, rel=1e-6)


def test_pvg32_example_matches_nonlinear(tmp_path):
    spec = importlib.util.spec_from_file_location("linearize_pvg32",
                                                  ROOT / "examples" / "linearize_pvg32.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "step.png"
    res = mod.main(str(out), verbose=False)
    assert out.exists() and out.stat().st_size > 1000
    lin, nl = res["dx_linear"][-1], res["dx_nonlinear"][-1]
    assert abs(nl) > 0 and abs(lin - nl) <= 0.2 * abs(nl)
    assert np.all(res["poles"].real < 0)  # a stable operating point
