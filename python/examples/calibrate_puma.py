"""Calibrate the PUMA 560 example data from pandas, and plot the position errors before and
after (with matplotlib, when it is installed).

    python python/examples/calibrate_puma.py [figure.png]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import robocal

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    try:
        import pandas as pd
    except ImportError:
        sys.exit("this example reads the data with pandas: pip install pandas")
    frame = pd.read_csv(ROOT / "examples" / "puma560-measurements.csv", comment="#")
    held = pd.read_csv(ROOT / "examples" / "puma560-validation.csv", comment="#")
    puma = robocal.Model.preset("puma560")
    c = robocal.calibrate(
        puma,
        frame,
        validate=[held],
        joint_unit="deg",
        length_unit="mm",
        joint_sigma=[0.007, 0.007, 0.007, 0.002, 0.002, 0.002],
        sigma=0.02,
    )
    print(c.parameters.to_pandas().head(8))
    _, errors = c.pose_errors("validate[0]")
    distances = np.linalg.norm(errors, axis=2)  # poses x (before, after) x markers
    before, after = distances[:, : distances.shape[1] // 2], distances[:, distances.shape[1] // 2 :]
    print(f"held-out poses: mean error {before.mean():.3f} mm before, {after.mean():.3f} mm after")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("(no matplotlib: no figure)")
        return
    figure, axes = plt.subplots(figsize=(7, 4))
    axes.hist(before.ravel(), bins=30, alpha=0.6, label="before")
    axes.hist(after.ravel(), bins=30, alpha=0.6, label="after")
    axes.set_xlabel("position error on held-out poses (mm)")
    axes.set_ylabel("markers")
    axes.legend()
    out = sys.argv[1] if len(sys.argv) > 1 else "puma560-errors.png"
    figure.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
