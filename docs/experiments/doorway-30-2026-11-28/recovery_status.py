"""One run of ``recovery-phase/doorway.csv`` re-simulated: what the stall
recovery decided each time its status changed (a route started, "no
route", ...), with its counts of routes driven and stalls without one.

    python docs/experiments/doorway-30-2026-11-28/recovery_status.py RUN_ID

e.g. RUN_ID doorway_stretch3_2h/safe/instructed/SM2ITH/seed6
(output: recovery_status_2h_safe_seed6.txt).
"""

import runpy
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
TRACE = runpy.run_path(str(HERE.parent / "final-2026-11-28" / "trace.py"))


def main(run_id):
    log = []

    def Record(new, kwargs):
        r = new.recovery
        log.append((kwargs["time_now"], r.status, r.routes, r.no_route))

    row, *_ = TRACE["ResimulateRun"](
        HERE / "recovery-phase" / "doorway.csv", "doorway", run_id, Record
    )
    print(f"{run_id} success {row['success']} recovery steps {row['recovery_steps']}")
    last = None
    for t, status, routes, no_route in log:
        if status and status != last:
            print(f"  {t:6.2f} {status}  routes {routes} no_route {no_route}")
        last = status
    print(f"final routes {log[-1][2]} no_route {log[-1][3]}")


if __name__ == "__main__":
    main(sys.argv[1])
