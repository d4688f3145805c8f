import sys; sys.path.insert(0, "/tmp/audit13")
from rig1 import build
from pvgraph.analysis import steady_state
S = build().compile(); op = steady_state(S)
print(op.sensitivity("node.port.p", ["node.p0", "node.V", "node.beta", "orifice.rho", "orifice.Cd"]))
# closed form turbulent: p = rho/2 (Q/(Cd A))^2 -> dp/drho = p/rho = 9645, dp/dCd = -2p/Cd = -2.797e7
print("closed dp/drho ~", op["node.port.p"]/870, "dp/dCd ~", -2*op["node.port.p"]/0.6)
for bad in (["node.nope"], ["node.port.p"], [3]):
    try: print(op.sensitivity("node.port.p", bad))
    except Exception as e: print(bad, type(e).__name__, str(e)[:200])
try: print(op.sensitivity("node.port.x", ["node.V"]))
except Exception as e: print("bad output", type(e).__name__, str(e)[:200])
