"""Overheads of the Python layer, measured against the Rust library and the command line.

1. ``Model.fk_batch`` of 100k configurations against the library's own loop over the same
   configurations (``cargo run --release -p robocal-python --example fk_rust``).
2. ``robocal.calibrate`` of a file of 1000 poses against ``robocal calibrate`` of it.

Build both in release first:

    cargo build --release && cargo build --release -p robocal-python --example fk_rust
    (cd python && maturin develop --release)
    cargo run --release --example make_campaign -- 1000 2 target/campaign-1000.csv
    python python/benches/bench.py target/campaign-1000.csv
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import robocal

ROOT = Path(__file__).resolve().parents[2]
RELEASE = ROOT / "target" / "release"


def best_of(runs: int, f: object) -> float:
    assert callable(f)
    best = float("inf")
    for _ in range(runs):
        started = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - started)
    return best


def main() -> None:
    n = 100_000
    i, j = np.meshgrid(np.arange(n), np.arange(6), indexing="ij")
    q = np.sin((i + j).astype(np.float64)) * 2.0  # as fk_rust.rs makes them
    puma = robocal.Model.preset("puma560")
    python = best_of(5, lambda: puma.fk_batch(q))
    print(f"python fk_batch of {n} configurations: {python * 1e3:.2f} ms (best of 5); checksum {puma.fk_batch(q).sum():.6e}")
    fk_rust = RELEASE / "examples" / "fk_rust"
    if fk_rust.exists():
        rust = subprocess.run([str(fk_rust), str(n)], capture_output=True, text=True, check=True)
        print(rust.stdout.strip())
    else:
        print(f"{fk_rust}: not built, the library's own fk time left out")
    if len(sys.argv) < 2:
        return
    data = sys.argv[1]
    flags = ["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.01",
             "--marker", "52,1,148", "--marker", "-38,61,121"]
    command = [str(RELEASE / "robocal"), "calibrate", "--model", "puma560", "--data", data, *flags, "--quiet"]

    def calibrate() -> None:
        robocal.calibrate(puma, data, joint_sigma=[0.007] * 3 + [0.002] * 3, sigma=0.01,
                          marker=[(52, 1, 148), (-38, 61, 121)], joint_unit="deg", length_unit="mm")

    # Interleaved, best of 20 each: a shared machine's load moves both alike.
    cli, python = float("inf"), float("inf")
    for _ in range(20):
        cli = min(cli, best_of(1, lambda: subprocess.run(command, capture_output=True, check=True)))
        python = min(python, best_of(1, calibrate))
    print(f"calibrate {data}: command line {cli * 1e3:.1f} ms (whole process), python {python * 1e3:.1f} ms "
          f"(best of 20 each, interleaved; python / command line = {python / cli:.3f})")


if __name__ == "__main__":
    main()
