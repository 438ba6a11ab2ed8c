"""How often the diagnosis names a hand-held or robot disturbance, and names nothing on clean
sessions, over seeds (simulated sessions of tests/gap/disturbance_cases.py: 120 s, an
orientation reference and a magnetometer; each effect at its realistic size).

Run: ``PYTHONPATH=. python tests/benchmarks/gap/bench_disturbances.py hand [seeds] [first]
[confounder_seeds]`` (or ``robot``). Prints per case the sessions where the effect was named
(alone or with others), where any disturbance was named that the session does not have, and
the wall time (and each seed's `explained` as it comes).
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "gap"))

from disturbance_cases import CONFOUNDERS, diagnose_case  # noqa: E402

from imucal.sim.effects import MOTION_EFFECTS  # noqa: E402

#: The cases per protocol: the clean session, each disturbance, and (hand-held) what they must
#: not be taken for.
CASES = {
    "hand": (None, *MOTION_EFFECTS, "reference_jitter", "mag_delay"),
    "robot": (None, *MOTION_EFFECTS),
}


def main(protocol: str, seeds: int = 10, first: int = 100, confounder_seeds: int = 5) -> None:
    for case in CASES[protocol]:
        named, wrong, others = 0, 0, Counter()
        t0 = time.perf_counter()
        n = confounder_seeds if case in CONFOUNDERS else seeds
        for seed in range(first, first + n):
            explained = diagnose_case(protocol, case, seed)["explained"]
            print(f"  {protocol} {case or 'clean'} seed {seed}: {explained}", flush=True)
            named += case in explained
            wrong += any(e in MOTION_EFFECTS and e != case for e in explained)
            others.update(e for e in explained if e != case)
        print(f"{protocol} {case or 'clean'}: named {named}/{n}, a disturbance it does "
              f"not have named {wrong}/{n}, others named {dict(others)}; "
              f"{time.perf_counter() - t0:.0f} s", flush=True)  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], *(int(a) for a in sys.argv[2:5]))
