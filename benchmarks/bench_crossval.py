"""Cost of the PVG 32 validation and its cross-validation (pvgraph validate --cross-validate).

    PYTHONPATH=$PWD python benchmarks/bench_crossval.py [repeats]

Side by side in one process: one scenario simulated with the tuned preset and with the rig's
return hose and Pb offset that the cross-validation identifies (one more restriction in the
load); the 19 scenarios by simulation (validate, 2 workers); the 14-fold cross-validation by
steady states on 1 and 2 workers. Medians of ``repeats`` runs (default 3; the
cross-validation once per worker count).
"""

import statistics
import sys
import time

from _machine import machine

from pvgraph.circuits import crossval, validation
from pvgraph.circuits.pvg32.parameters import report_tuned
from pvgraph.units import bar, lpm_per_bar


def timed(fn, repeats):
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out), out


def main(repeats: int = 3):
    p = report_tuned()
    hose = p.model_copy(update={"rig": p.rig.model_copy(update={
        "return_hose_K": lpm_per_bar(23.0), "pb_sensor_offset": bar(-0.475)})})
    print(machine())
    rows = []
    t_sep, _ = timed(lambda: validation.run_scenario("test-9", p), repeats)
    t_hose, _ = timed(lambda: validation.run_scenario("test-9", hose), repeats)
    rows.append(("test-9 simulated, tuned preset", t_sep))
    rows.append(("test-9 simulated, with the return hose", t_hose))
    t_val, _ = timed(lambda: validation.validate(p, workers=2), 1)
    rows.append(("validate, 19 scenarios, 2 workers", t_val))
    for w in (1, 2):
        t, _ = timed(lambda: crossval.cross_validate(workers=w), 1)
        rows.append((f"cross-validation, 14 folds, {w} worker(s)", t))
    for label, t in rows:
        print(f"| {label} | {t:.2f} |")
    print(f"with hose / preset: {t_hose / t_sep:.2f}x")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
