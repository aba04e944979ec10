"""robocal: kinematic calibration of robot arms, from Python.

A thin layer over the Rust library: every number is computed by it, every file read by its
readers, and the reports are the command line's. Units inside are millimetres and radians
(millimetres for prismatic joints); data given as arrays is in ``joint_unit`` and
``length_unit`` (radians and metres unless told).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Union

import numpy as np

from ._errors import EstimationError, InputError, RobocalError
from ._robocal import Calibration as _Calibration
from ._robocal import Model, __version__, presets, studies
from ._robocal import calibrate_source as _calibrate_source
from ._robocal import evaluate as _evaluate
from ._robocal import observability as _observability
from ._robocal import plan as _plan
from ._robocal import measurements_csv as _measurements_csv
from ._robocal import simulate as _simulate

__all__ = [
    "Calibration",
    "EstimationError",
    "InputError",
    "Model",
    "Parameters",
    "RobocalError",
    "__version__",
    "calibrate",
    "evaluate",
    "observability",
    "plan",
    "presets",
    "reproduce",
    "simulate",
    "studies",
]


@dataclass(frozen=True)
class Parameters:
    """The identified parameters: names, estimated errors and standard errors (in ``units``:
    deg for angles, mm for lengths), as the report lists them."""

    names: list[str]
    estimates: np.ndarray
    standard_errors: np.ndarray
    units: list[str]

    def to_pandas(self) -> Any:
        """The parameters as a DataFrame indexed by name (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(
            {"estimate": self.estimates, "standard_error": self.standard_errors, "unit": self.units},
            index=pd.Index(self.names, name="parameter"),
        )


class Calibration:
    """A finished calibration: the report, the parameters and their covariance, the errors
    pose by pose, and the calibrated model."""

    def __init__(self, inner: _Calibration) -> None:
        self._inner = inner

    @property
    def parameters(self) -> Parameters:
        """The identified parameters (deg, mm)."""
        i = self._inner
        return Parameters(i.names, i.estimates, i.standard_errors, i.units)

    @property
    def covariance(self) -> np.ndarray:
        """The estimate's covariance in mm and rad, rows as ``covariance_names``."""
        return self._inner.covariance

    @property
    def covariance_names(self) -> list[str]:
        """The names of the covariance's rows and columns."""
        return self._inner.covariance_names

    @property
    def rank(self) -> int:
        """The numerical rank of the identified system."""
        return self._inner.rank

    @property
    def held(self) -> list[str]:
        """The combinations held because the poses cannot identify them."""
        return self._inner.held

    @property
    def model(self) -> Model:
        """The calibrated model."""
        return self._inner.model

    @property
    def sets(self) -> list[str]:
        """The scored sets: ``training``, then each held-out set (marker data)."""
        return self._inner.sets

    def pose_errors(self, set: str = "training") -> tuple[np.ndarray, np.ndarray]:
        """The poses' lines and their position errors (mm): poses x (before, after) x 3 for
        one marker, poses x (2 markers) x 3 in general (stage-major)."""
        return self._inner.pose_errors(set)

    def model_toml(self) -> str:
        """The calibrated model as TOML with its markers, as ``--out-model`` writes it."""
        return self._inner.model_toml()

    def report(self) -> str:
        """The report as ``robocal calibrate`` prints it."""
        return self._inner.report()

    def to_json(self) -> str:
        """The JSON report as ``robocal calibrate --json`` writes it."""
        return self._inner.to_json()

    def __repr__(self) -> str:
        return repr(self._inner)


PathLike = Union[str, "os.PathLike[str]"]


def _source(
    model: Model,
    data: Any,
    markers: Any,
    name: str,
    pose_sigma: Any = None,
    orientations: Any = None,
) -> tuple[tuple[str, Optional[str], Optional[str]], bool]:
    """A data set as the extension takes it (name, file, CSV text), and whether it came as
    arrays (whose units default to rad and m)."""
    if isinstance(data, (str, os.PathLike)):
        path = os.fspath(data)
        return (path, path, None), False
    if hasattr(data, "to_csv") and markers is None:  # a pandas DataFrame, columns as in a file
        return ("DataFrame" if name == "arrays" else name, None, data.to_csv(index=False)), False
    if markers is None:
        raise InputError(f"{name}: give the markers with the joints, a DataFrame or a file", field="markers")
    joints = np.ascontiguousarray(data, dtype=np.float64)
    points = np.ascontiguousarray(markers, dtype=np.float64)
    if points.ndim == 3:  # poses x markers x 3
        points = points.reshape(points.shape[0], -1)
    if joints.ndim != 2 or points.ndim != 2:
        raise InputError(f"{name}: joints and markers are 2-D arrays, one row per pose", field="joints")
    sigma = None if pose_sigma is None else np.ascontiguousarray(pose_sigma, dtype=np.float64)
    quaternions = None if orientations is None else np.ascontiguousarray(orientations, dtype=np.float64)
    return (name, None, _measurements_csv(model, joints, points, sigma, quaternions)), True


def calibrate(
    model: Model,
    joints: Any,
    markers: Any = None,
    *,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    estimator: Optional[str] = None,
    joint_sigma: Union[Sequence[float], np.ndarray, None] = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    noise: Optional[PathLike] = None,
    params: Union[str, Sequence[str]] = "joints",
    hold: Sequence[str] = (),
    keep: Sequence[str] = (),
    validate: Sequence[Any] = (),
    folds: Optional[int] = None,
    select: Optional[str] = None,
    prior: Optional[str] = None,
    loss: Optional[str] = None,
    fixed_base: bool = False,
    fixed_markers: bool = False,
    fixed_tool: bool = False,
    marker: Sequence[Sequence[float]] = (),
    tool: Optional[Sequence[float]] = None,
    use_markers: Optional[Sequence[int]] = None,
    iterations: int = 200,
    pose_sigma: Any = None,
    orientations: Any = None,
) -> Calibration:
    """Calibrate ``model`` as ``robocal calibrate`` does; see the stub for every option."""
    given_units = joint_unit is not None or length_unit is not None
    arrays = False
    if isinstance(joints, (list, tuple)) and markers is None and all(
        isinstance(j, (str, os.PathLike)) for j in joints
    ):  # observation files, fitted together
        sources = [(os.fspath(p), os.fspath(p), None) for p in joints]
    else:
        source, arrays = _source(model, joints, markers, "arrays", pose_sigma, orientations)
        sources = [source]
    held_out = []
    for k, v in enumerate(validate):
        if isinstance(v, tuple):
            s, _ = _source(model, v[0], v[1], f"validate[{k}]")
        else:
            s, _ = _source(model, v, None, f"validate[{k}]")
        held_out.append(s)
    if arrays and not given_units:
        joint_unit, length_unit = "rad", "m"
    flags = _flags(
        joint_unit=joint_unit,
        length_unit=length_unit,
        estimator=estimator,
        joint_sigma=joint_sigma,
        sigma=sigma,
        sigma_orientation=sigma_orientation,
        noise=noise,
        params=params,
        hold=hold,
        keep=keep,
        select=select,
        prior=prior,
        loss=loss,
        folds=folds,
        fixed_base=fixed_base,
        fixed_markers=fixed_markers,
        fixed_tool=fixed_tool,
        marker=marker,
        tool=tool,
        use_markers=use_markers,
        iterations=iterations,
    )
    return Calibration(_calibrate_source(model, sources, held_out, flags))


def _flags(
    *,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    estimator: Optional[str] = None,
    joint_sigma: Any = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    noise: Optional[PathLike] = None,
    params: Union[str, Sequence[str]] = "joints",
    hold: Sequence[str] = (),
    keep: Sequence[str] = (),
    select: Optional[str] = None,
    prior: Optional[str] = None,
    loss: Optional[str] = None,
    folds: Optional[int] = None,
    fixed_base: bool = False,
    fixed_markers: bool = False,
    fixed_tool: bool = False,
    marker: Sequence[Sequence[float]] = (),
    tool: Optional[Sequence[float]] = None,
    use_markers: Optional[Sequence[int]] = None,
    iterations: int = 200,
) -> dict[str, Any]:
    """The options as the extension takes them."""
    return {
        "joint_unit": joint_unit,
        "length_unit": length_unit,
        "estimator": estimator,
        "joint_sigma": None if joint_sigma is None else [float(s) for s in joint_sigma],
        "sigma": sigma,
        "sigma_orientation": sigma_orientation,
        "noise": None if noise is None else os.fspath(noise),
        "params": [params] if isinstance(params, str) else list(params),
        "hold": list(hold),
        "keep": list(keep),
        "select": select,
        "prior": prior,
        "loss": loss,
        "folds": folds,
        "fixed_base": fixed_base,
        "fixed_markers": fixed_markers,
        "fixed_tool": fixed_tool,
        "marker": [[float(c) for c in m] for m in marker],
        "tool": None if tool is None else [float(c) for c in tool],
        "markers": None if use_markers is None else list(use_markers),
        "iterations": iterations,
    }


def evaluate(
    model: Model,
    data: Any,
    markers: Any = None,
    *,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    joint_sigma: Any = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    noise: Optional[PathLike] = None,
    use_markers: Optional[Sequence[int]] = None,
) -> dict[str, Any]:
    """``model`` scored as it stands on ``data``, as ``robocal evaluate`` scores it."""
    source, arrays = _source(model, data, markers, "arrays")
    if arrays and joint_unit is None and length_unit is None:
        joint_unit, length_unit = "rad", "m"
    flags = _flags(
        joint_unit=joint_unit,
        length_unit=length_unit,
        joint_sigma=joint_sigma,
        sigma=sigma,
        sigma_orientation=sigma_orientation,
        noise=noise,
        use_markers=use_markers,
    )
    result: dict[str, Any] = json.loads(_evaluate(model, source, flags))
    return result


def _design_flags(
    params: Union[str, Sequence[str]],
    measured: str,
    joint_sigma: Any,
    sigma: Optional[float],
    sigma_orientation: Optional[float],
    joint_unit: str,
    length_unit: str,
) -> dict[str, Any]:
    return {
        "params": [params] if isinstance(params, str) else list(params),
        "measured": measured,
        "joint_sigma": None if joint_sigma is None else [float(s) for s in joint_sigma],
        "sigma": sigma,
        "sigma_orientation": sigma_orientation,
        "joint_unit": joint_unit,
        "length_unit": length_unit,
    }


def observability(
    model: Model,
    poses: Any,
    *,
    params: Union[str, Sequence[str]] = "joints",
    measured: str = "position",
    joint_sigma: Any = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    joint_unit: str = "rad",
    length_unit: str = "m",
) -> dict[str, Any]:
    """The observability indices O1-O5 of ``poses``, as ``robocal observability`` gives them."""
    flags = _design_flags(params, measured, joint_sigma, sigma, sigma_orientation, joint_unit, length_unit)
    result: dict[str, Any] = _observability(model, np.ascontiguousarray(poses, dtype=np.float64), flags)
    return result


def plan(
    model: Model,
    points: int,
    *,
    candidates: int = 5000,
    criterion: str = "d",
    seed: int = 1,
    params: Union[str, Sequence[str]] = "joints",
    measured: str = "position",
    joint_sigma: Any = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    joint_unit: str = "rad",
    length_unit: str = "m",
) -> dict[str, Any]:
    """``points`` poses planned as ``robocal plan`` plans them (the same seed, the same poses)."""
    flags = _design_flags(params, measured, joint_sigma, sigma, sigma_orientation, joint_unit, length_unit)
    result: dict[str, Any] = _plan(model, points, candidates, criterion, seed, flags)
    return result


def simulate(
    study: str, *, threads: Optional[int] = None, noise: Optional[PathLike] = None, quiet: bool = False
) -> dict[str, Any]:
    """Run a Monte Carlo study (a preset name or a TOML file) as ``robocal simulate`` does."""
    result: dict[str, Any] = _simulate(study, threads, None if noise is None else os.fspath(noise), quiet)
    return result


def reproduce(*, threads: Optional[int] = None, quiet: bool = False) -> list[dict[str, Any]]:
    """The paper's two studies, as ``robocal reproduce`` runs them."""
    return [simulate(name, threads=threads, quiet=quiet) for name in ("paper-table1", "paper-table2")]
