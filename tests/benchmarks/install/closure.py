"""What each dependency of imu-platform-cal costs in the environment it is installed in.

Per dependency of the distribution (with the extras given on the command line): the packages
its requirements bring (its closure), their megabytes on disk, and the megabytes of the
packages it alone brings (in no other dependency's closure), from the installed distributions'
RECORD files. Run it with the venv's python::

    python tests/benchmarks/install/closure.py          # run-time dependencies
    python tests/benchmarks/install/closure.py test     # with the test extra
"""

from __future__ import annotations

import re
import sys
from importlib import metadata


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


DISTS = {_norm(d.metadata["Name"]): d for d in metadata.distributions()}


def _megabytes(dist) -> float:
    total = 0
    for file in dist.files or []:
        try:
            total += file.locate().stat().st_size
        except OSError:
            continue
    return total / 1e6


def _requires(dist, extras: tuple[str, ...] = ()) -> list[str]:
    out = []
    for requirement in dist.requires or []:
        name, _, marker = requirement.partition(";")
        if "extra ==" in marker and not any(f'extra == "{e}"' in marker for e in extras):
            continue
        key = _norm(re.split(r"[ <>=!~\[(]", name.strip(), maxsplit=1)[0])
        if key in DISTS:
            out.append(key)
    return out


def _closure(name: str, seen: set[str] | None = None) -> set[str]:
    seen = set() if seen is None else seen
    if name not in seen:
        seen.add(name)
        for requirement in _requires(DISTS[name]):
            _closure(requirement, seen)
    return seen


def main(extras: tuple[str, ...]) -> None:
    top = _requires(DISTS["imu-platform-cal"], extras)
    closures = {t: _closure(t) for t in top}
    size = {name: _megabytes(dist) for name, dist in DISTS.items()}
    print(f"{'dependency':32s} {'brings':>6s} {'MB':>7s} {'MB alone':>8s}  it alone brings")
    for t in sorted(top, key=lambda t: -sum(size[n] for n in closures[t])):
        others = set().union(*(closures[u] for u in top if u != t))
        alone = closures[t] - others
        print(f"{t:32s} {len(closures[t]):6d} {sum(size[n] for n in closures[t]):7.1f} "
              f"{sum(size[n] for n in alone):8.1f}  {', '.join(sorted(alone - {t}))}")  # fmt: skip
    every = set().union(*closures.values())
    print(f"all: {len(every)} packages, {sum(size[n] for n in every):.1f} MB")


if __name__ == "__main__":
    main(tuple(sys.argv[1:]))
