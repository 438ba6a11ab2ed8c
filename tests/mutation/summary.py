"""The score per package of a mutation results file (``run.py``'s JSON lines), the mutants
listed in ``equivalent.txt`` scored apart, and the surviving mutants.

Usage::

    python tests/mutation/summary.py RESULTS.jsonl
"""

from __future__ import annotations

import json
import sys
from collections import Counter, defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import load_equivalent, package_of, summary  # noqa: E402


def main(argv: list[str]) -> int:
    equivalent = load_equivalent()
    counts: dict[str, Counter] = defaultdict(Counter)
    survivors = []
    for line in Path(argv[0]).read_text().splitlines():
        r = json.loads(line)
        status = r["status"].split(":")[0]
        if status == "survived" and r["mutant"] in equivalent:
            status = "equivalent"
        if status == "survived":
            survivors.append(f"{r['mutant']}  {r['original']!r} -> {r['replacement']!r}")
        counts[package_of(r["mutant"].split(":")[0])][status] += 1
    print(summary(counts))
    print("\nsurvived:\n" + "\n".join(survivors))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
