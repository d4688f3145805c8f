"""Parts joined the way they are built: a shaker table driven in position, index reduction.

    Sine -> PositionInput -> table (5 kg) == fixture (2 kg)      (rigidly bolted: one flange)
                                  |
                               spring k + damper c
                                  |
                               payload (1 kg)

The table and the fixture are two ``SpoolMass`` bodies on one flange and the table is moved by a
``PositionInput`` along ``y = Y sin(w t)``: index three as written. The compiler differentiates
the sine twice and the masses' velocity equations once, and reports what it did
(``system.index_report()``). The payload on its spring-damper is the classic base-excited
oscillator; in steady state its amplitude is ``Y * T(w)`` with the transmissibility

    T(w) = sqrt((k^2 + (c w)^2) / ((k - m w^2)^2 + (c w)^2))

and the drive must supply ``(m_table + m_fixture) * y''`` plus the spring-damper force.

Run: ``python examples/shaker_table.py``.
"""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from pvgraph.components.mechanical import (PositionInput, SpoolMass, TwoFlangeDamper,  # noqa: E402
                                   TwoFlangeSpring)
from pvgraph.components.signal import Sine  # noqa: E402
from pvgraph import Circuit  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402

Y, F_HZ = 1e-3, 5.0                      # drive amplitude [m], frequency [Hz]
M_TABLE, M_FIXTURE, M_PAYLOAD = 5.0, 2.0, 1.0
K, C = 4e3, 25.0                         # payload mount [N/m], [N s/m]


def build() -> Circuit:
    c = Circuit("shaker")
    drive = c.add("drive", PositionInput())
    sine = c.add("sine", Sine(amplitude=Y, f=F_HZ))
    table = c.add("table", SpoolMass(m=M_TABLE))
    fixture = c.add("fixture", SpoolMass(m=M_FIXTURE))
    payload = c.add("payload", SpoolMass(m=M_PAYLOAD))
    spring = c.add("mount_spring", TwoFlangeSpring(k=K))
    damper = c.add("mount_damper", TwoFlangeDamper(d=C))
    c.connect(sine.y, drive.u)
    c.connect(drive.flange, table.flange, fixture.flange, spring.a, damper.a)
    c.connect(spring.b, damper.b, payload.flange)
    return c


def main(outdir=".") -> dict:
    system = build().compile()
    print(system.index_report())
    sol = simulate(system, 3.0, rtol=1e-8, max_step=1e-3)
    w = 2.0 * math.pi * F_HZ
    transmissibility = math.sqrt((K ** 2 + (C * w) ** 2)
                                 / ((K - M_PAYLOAD * w ** 2) ** 2 + (C * w) ** 2))
    last = sol.t > 2.0                   # the payload's free motion has decayed (e^-12.5t)
    x_payload = np.max(np.abs(sol["payload.flange.x"][last]))
    # the drive's force on the table assembly: -drive.flange.f
    mount = -sol["mount_spring.a.f"] - sol["mount_damper.a.f"]
    inertial = (M_TABLE + M_FIXTURE) * -Y * w * w * np.sin(w * sol.t)
    force_error = np.max(np.abs(-sol["drive.flange.f"] - (inertial - mount)))
    print(f"payload amplitude {x_payload * 1e3:.4f} mm, transmissibility predicts "
          f"{Y * transmissibility * 1e3:.4f} mm")
    print(f"drive force amplitude {np.max(np.abs(sol['drive.flange.f'])):.1f} N; largest "
          f"deviation from (m_table + m_fixture) y'' + mount force: {force_error:.2e} N")
    return {"x_payload": x_payload, "x_expected": Y * transmissibility,
            "force_error": force_error,
            "force_scale": (M_TABLE + M_FIXTURE) * Y * w * w,
            "report": system.index_report(),
            "states": [n for n, d in zip(system.names, system.differential) if d]}


if __name__ == "__main__":
    main()
