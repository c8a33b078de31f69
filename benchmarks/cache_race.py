"""Race two processes writing the same feature cache entry; count crashed writers and bad entries.

Each of ``--pairs`` rounds starts two processes that each write (and read back) the
same entry ``--writes`` times, then checks the entry left behind::

    PYTHONPATH=src python benchmarks/cache_race.py --pairs 40 --writes 20

Prints ``N pairs: C with a crashed writer, B with a bad entry left``. Measured on the
development machine (2 shared cores) with ``--pairs 10``: 0 and 0; the cache before
``qdcnn.direction.feature_cache`` (one fixed temporary name) crashed a writer in 10 of 10.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

WRITER = textwrap.dedent(
    """
    import sys
    from pathlib import Path

    import numpy as np

    from qdcnn.batch import Failure
    from qdcnn.direction.feature_cache import CachedFeatures, read_entry, write_entry

    path, seed, writes = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    n, groupings = 2000, ("image-split", "kmeans", "spectral")
    rng = np.random.default_rng(seed)
    readable = np.ones(n, bool)
    readable[::7] = False
    status = np.where(readable, "ok", "unreadable")
    failures = [Failure(f"f{i}", "bad") for i in np.flatnonzero(~readable)]
    for _ in range(writes):
        feats = {g: rng.normal(size=(n, 2)) for g in groupings}
        entry = CachedFeatures(feats, {g: status for g in groupings}, readable, failures, 0.5)
        write_entry(path, entry, groupings)
        if read_entry(path, groupings, n, 2, on_bad=lambda p, r: sys.exit(f"bad: {r}")) is None:
            sys.exit("entry vanished")
    """
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=40)
    parser.add_argument("--writes", type=int, default=20)
    args = parser.parse_args()
    from qdcnn.direction.feature_cache import read_entry

    crashed = bad = 0
    for _ in range(args.pairs):
        path = Path(tempfile.mkdtemp()) / "features-race.npz"
        procs = [
            subprocess.Popen(
                [sys.executable, "-c", WRITER, str(path), str(seed), str(args.writes)],
                env=dict(os.environ),
                stderr=subprocess.DEVNULL,
            )
            for seed in (1, 2)
        ]
        crashed += any(p.wait() != 0 for p in procs)
        groupings = ("image-split", "kmeans", "spectral")
        if read_entry(path, groupings, 2000, 2, on_bad=lambda p, r: None) is None:
            bad += 1  # missing or failed the checks
    print(f"{args.pairs} pairs: {crashed} with a crashed writer, {bad} with a bad entry left")


if __name__ == "__main__":
    main()
