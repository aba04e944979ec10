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
from ._robocal import calibrate_tree as _calibrate_tree
from ._robocal import compensate as _compensate
from ._robocal import evaluate as _evaluate
from ._robocal import evaluate_tree as _evaluate_tree
from ._robocal import observability as _observability
from ._robocal import plan as _plan
from ._robocal import measurements_csv as _measurements_csv
from ._robocal import simulate as _simulate
from ._robocal import table_csv as _table_csv

__all__ = [
    "Calibration",
    "EstimationError",
    "InputError",
    "Model",
    "Parameters",
    "RobocalError",
    "__version__",
    "CameraViews",
    "Coordinates",
    "Observations",
    "PairDistances",
    "PlaneContacts",
    "PointDistances",
    "calibrate",
    "calibrate_tree",
    "Compensation",
    "compensate",
    "evaluate",
    "evaluate_tree",
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
    def branches(self) -> dict[str, Model]:
        """A tree's calibrated branches by tip link (empty for a chain)."""
        return dict(self._inner.branches)

    @property
    def sets(self) -> list[str]:
        """The scored sets, as the JSON report's ``sets``: ``training``, then each held-out
        set, the held-out sets pooled (several) and the cross-validation (``folds``)."""
        return self._inner.sets

    def pose_errors(self, set: str = "training") -> tuple[np.ndarray, np.ndarray]:
        """The poses' lines and their marker position errors (mm): poses x (before, after) x 3
        for one marker, poses x (2 markers) x 3 in general (stage-major); NaN where not
        measured; no poses for a set without markers."""
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

_UNITS = {"rad": "rad", "deg": "deg", "m": "m", "mm": "mm"}


def _column(values: Any, n: int, name: str) -> np.ndarray:
    """One value per row: an array of ``n``, or one number for every row."""
    array = np.asarray(values, dtype=np.float64)
    if array.ndim == 0:
        return np.full(n, float(array))
    if array.shape != (n,):
        raise InputError(f"{name}: expected {n} values (one per row), got shape {array.shape}", field=name)
    return array


class Observations:
    """Observations of one measuring session, as the columns of an observation file: the
    library's reader reads them (the same checks, the same numbers as the file). Built by the
    typed classes from arrays (``PairDistances``, ``PointDistances``, ``PlaneContacts``,
    ``Coordinates``, ``CameraViews``) or by ``from_pandas`` from a DataFrame."""

    def __init__(
        self,
        joints: Any,
        columns: Sequence[tuple[str, Any]] = (),
        *,
        name: str,
        joint_unit: str = "rad",
        length_unit: str = "m",
        joints_b: Any = None,
        constant: Sequence[tuple[str, str]] = (),
    ) -> None:
        if joint_unit not in ("rad", "deg"):
            raise InputError(f"joint_unit: `{joint_unit}`: expected rad or deg", field="joint_unit")
        if length_unit not in ("m", "mm"):
            raise InputError(f"length_unit: `{length_unit}`: expected m or mm", field="length_unit")
        self.name = name
        self.joint_unit = joint_unit
        self.length_unit = length_unit
        self._frame: Optional[str] = None
        self._joints = None if joints is None else np.asarray(joints, dtype=np.float64)
        self._joints_b = None if joints_b is None else np.asarray(joints_b, dtype=np.float64)
        n = 0 if self._joints is None else len(self._joints)
        if self._joints is not None and self._joints.ndim != 2:
            raise InputError(f"{name}: joints: a 2-D array, one row per pose", field="joints")
        self._columns = [(c, _column(v, n, c)) for c, v in columns if v is not None]
        self._constant = list(constant)

    @classmethod
    def from_pandas(
        cls, frame: Any, *, name: str = "observations", joint_unit: str = "rad", length_unit: str = "m"
    ) -> "Observations":
        """A DataFrame with an observation file's columns (the joints by name, then
        ``distance``, ``point``, ``plane``, ``x``..``yaw``, ``camera``, ``sigma``, ``kind``...),
        its lengths and angles in ``length_unit`` and ``joint_unit``."""
        made = cls(None, name=name, joint_unit=joint_unit, length_unit=length_unit)
        made._frame = frame.to_csv(index=False)
        return made

    def _units_line(self) -> str:
        return f"# units: joints={self.joint_unit}, lengths={self.length_unit}"

    def to_csv(self, model: Model) -> str:
        """The observation file these observations make for ``model`` (its joint names)."""
        if self._frame is not None:
            return self._units_line() + "\n" + self._frame
        assert self._joints is not None
        names = list(model.joint_names)
        if self._joints.shape[1] != len(names):
            raise InputError(
                f"{self.name}: joints: {self._joints.shape[1]} columns for the {len(names)} joints of {model.name}",
                field="joints",
            )
        columns = [self._joints[:, k] for k in range(len(names))]
        if self._joints_b is not None:
            if self._joints_b.shape != self._joints.shape:
                raise InputError(f"{self.name}: joints_b: expected the shape of joints", field="joints_b")
            names += [f"{j}_b" for j in model.joint_names]
            columns += [self._joints_b[:, k] for k in range(self._joints_b.shape[1])]
        names += [c for c, _ in self._columns]
        columns += [v for _, v in self._columns]
        return _table_csv(self._units_line(), names, [np.ascontiguousarray(c) for c in columns], self._constant)

    def __repr__(self) -> str:
        return f"robocal.{type(self).__name__}({self.name!r})"


class PairDistances(Observations):
    """Distances (ball bar, tape) between the tool point at two poses: ``joints`` and
    ``joints_b`` (n x dof each), ``distance`` (n), ``sigma`` (one or n; default 0.01 mm)."""

    def __init__(
        self,
        joints: Any,
        joints_b: Any,
        distance: Any,
        *,
        sigma: Any = None,
        name: str = "pairs",
        joint_unit: str = "rad",
        length_unit: str = "m",
    ) -> None:
        super().__init__(joints, [("distance", distance), ("sigma", sigma)], name=name, joint_unit=joint_unit,
                         length_unit=length_unit, joints_b=joints_b)


class PointDistances(Observations):
    """Distances from the tool point to fixed points (a ball bar's centre, a laser tracker
    measuring range only): ``joints`` (n x dof), ``distance`` (n), ``point`` (the fixed point's
    number, 1, 2, ...: one or n; default 1), ``sigma`` (one or n; default 0.01 mm)."""

    def __init__(
        self,
        joints: Any,
        distance: Any,
        *,
        point: Any = None,
        sigma: Any = None,
        name: str = "points",
        joint_unit: str = "rad",
        length_unit: str = "m",
    ) -> None:
        super().__init__(joints, [("distance", distance), ("point", point), ("sigma", sigma)], name=name,
                         joint_unit=joint_unit, length_unit=length_unit)


class PlaneContacts(Observations):
    """The tool point touching planes: ``joints`` (n x dof), ``plane`` (the plane's number,
    1, 2, ...: one or n; default 1), ``sigma`` (one or n; default 0.01 mm)."""

    def __init__(
        self,
        joints: Any,
        plane: Any = 1,
        *,
        sigma: Any = None,
        name: str = "contacts",
        joint_unit: str = "rad",
        length_unit: str = "m",
    ) -> None:
        super().__init__(joints, [("plane", plane), ("sigma", sigma)], name=name, joint_unit=joint_unit,
                         length_unit=length_unit)


class Coordinates(Observations):
    """Coordinates of the tool in the measuring frame, any of them (NaN where not measured):
    ``x``, ``y``, ``z`` (length unit), ``roll``, ``pitch``, ``yaw`` (joint unit, ``R = Rz(yaw)
    Ry(pitch) Rx(roll)``), each n values; ``sigma`` and ``sigma_angle`` (one or n; default
    0.01 mm and 0.01 deg)."""

    def __init__(
        self,
        joints: Any,
        *,
        x: Any = None,
        y: Any = None,
        z: Any = None,
        roll: Any = None,
        pitch: Any = None,
        yaw: Any = None,
        sigma: Any = None,
        sigma_angle: Any = None,
        name: str = "coordinates",
        joint_unit: str = "rad",
        length_unit: str = "m",
    ) -> None:
        given = [("x", x), ("y", y), ("z", z), ("roll", roll), ("pitch", pitch), ("yaw", yaw)]
        given += [("sigma", sigma), ("sigma_angle", sigma_angle)]
        super().__init__(joints, given, name=name, joint_unit=joint_unit, length_unit=length_unit)


class CameraViews(Observations):
    """A camera's views of its target: ``views`` (n x 6: the target's pose in the camera's
    frame, x, y, z in the length unit, roll, pitch, yaw in the joint unit), ``camera``
    ``hand`` (on the arm, the target fixed) or ``world`` (fixed, the target on the arm);
    ``sigma`` and ``sigma_angle`` (one or n; default 0.5 mm and 0.1 deg)."""

    def __init__(
        self,
        joints: Any,
        views: Any,
        *,
        camera: str = "hand",
        sigma: Any = None,
        sigma_angle: Any = None,
        name: str = "camera",
        joint_unit: str = "rad",
        length_unit: str = "m",
    ) -> None:
        v = np.asarray(views, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 6:
            raise InputError(f"{name}: views: expected n x 6 (x, y, z, roll, pitch, yaw), got {v.shape}",
                             field="views")
        axes = [(c, v[:, k]) for k, c in enumerate(("x", "y", "z", "roll", "pitch", "yaw"))]
        super().__init__(joints, [*axes, ("sigma", sigma), ("sigma_angle", sigma_angle)], name=name,
                         joint_unit=joint_unit, length_unit=length_unit, constant=[("camera", camera)])


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
    if isinstance(data, Observations):
        return (data.name, None, data.to_csv(model)), False
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
    joints: Any = None,
    markers: Any = None,
    *,
    observations: Sequence[Union[PathLike, Observations]] = (),
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
    per_session: Sequence[str] = (),
    validate: Sequence[Any] = (),
    folds: Optional[int] = None,
    select: Optional[str] = None,
    prior: Union[str, Sequence[str], None] = None,
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
        isinstance(j, (str, os.PathLike, Observations)) for j in joints
    ):  # observation files, fitted together
        observations, joints = list(joints), None
    if len(observations) > 0:
        if joints is not None or markers is not None:
            raise InputError("give marker data or observations, not both", field="observations")
        sources = [_source(model, o, None, "observations")[0] for o in observations]
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
        per_session=per_session,
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


def calibrate_tree(
    urdf: PathLike,
    views: Sequence[Any],
    *,
    tips: Sequence[str] = (),
    base_link: Optional[str] = None,
    validate: Sequence[Any] = (),
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    estimator: Optional[str] = None,
    joint_sigma: Union[Sequence[float], np.ndarray, None] = None,
    params: Union[str, Sequence[str]] = "joints",
    hold: Sequence[str] = (),
    keep: Sequence[str] = (),
    per_session: Sequence[str] = (),
    prior: Union[str, Sequence[str], None] = None,
    select: Optional[str] = None,
    loss: Optional[str] = None,
    iterations: int = 200,
    folds: Optional[int] = None,
) -> Calibration:
    """Calibrate the tree of ``urdf`` from views between its branches, as ``robocal calibrate``
    calibrates view files; see the stub."""

    sources = [_view_source(v, f"views[{k}]") for k, v in enumerate(views)]
    held_out = [_view_source(v, f"validate[{k}]") for k, v in enumerate(validate)]
    flags = _flags(joint_unit=joint_unit, length_unit=length_unit, estimator=estimator, joint_sigma=joint_sigma,
                   params=params, hold=hold, keep=keep, per_session=per_session, prior=prior, loss=loss,
                   iterations=iterations, folds=folds, select=select)
    return Calibration(_calibrate_tree(os.fspath(urdf), list(tips), base_link, sources, held_out, flags))


def _view_source(data: Any, name: str) -> tuple[str, Optional[str], Optional[str]]:
    """A view file's path or a DataFrame of its columns, as the extension takes it."""
    if isinstance(data, (str, os.PathLike)):
        return (os.fspath(data), os.fspath(data), None)
    if hasattr(data, "to_csv"):
        return (name, None, data.to_csv(index=False))
    raise InputError(f"{name}: a view file's path or a DataFrame with its columns", field="views")


def evaluate_tree(
    urdf: PathLike,
    views: Any,
    *,
    tips: Sequence[str] = (),
    base_link: Optional[str] = None,
    branches: Optional[PathLike] = None,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    joint_sigma: Any = None,
) -> dict[str, Any]:
    """The tree of ``urdf`` scored as it stands on ``views``, as ``robocal evaluate`` scores a
    file of views; see the stub."""
    flags = _flags(joint_unit=joint_unit, length_unit=length_unit, joint_sigma=joint_sigma)
    source = _view_source(views, "views")
    folder = None if branches is None else os.fspath(branches)
    result: dict[str, Any] = json.loads(
        _evaluate_tree(os.fspath(urdf), list(tips), base_link, folder, source, flags)
    )
    return result


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
    per_session: Sequence[str] = (),
    select: Optional[str] = None,
    prior: Union[str, Sequence[str], None] = None,
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
    """The options as the extension takes them; a count that is not a whole number in range
    is an ``InputError`` on its field (as the command line's usage error), not a TypeError."""
    for field, value, least in (("folds", folds, 2), ("iterations", iterations, 1)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < least):
            raise InputError(f"{field}: {value!r}: expected a whole number >= {least}", field=field)
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
        "per_session": list(per_session),
        "select": select,
        "prior": [] if prior is None else [prior] if isinstance(prior, str) else list(prior),
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


class Compensation:
    """A compensated program: per target (in the order given) its line, whether it is reached,
    the joint values to send and their change from the seed (rad; mm for prismatic joints; NaN
    where unreachable), the remaining and the uncompensated errors (mm, deg), the iterations,
    and why a target cannot be reached."""

    def __init__(self, out: dict[str, Any]) -> None:
        self.lines: np.ndarray = out["lines"]
        self.reached: np.ndarray = out["reached"]
        self.joints: np.ndarray = out["joints"]
        self.change: np.ndarray = out["change"]
        self.error_mm: np.ndarray = out["error_mm"]
        self.error_deg: np.ndarray = out["error_deg"]
        self.before_mm: np.ndarray = out["before_mm"]
        self.before_deg: np.ndarray = out["before_deg"]
        self.iterations: np.ndarray = out["iterations"]
        self.reasons: list[Optional[str]] = out["reasons"]
        self._report: str = out["report"]
        self._csv: str = out["csv"]
        self._json: str = out["json"]

    def report(self) -> str:
        """The report as ``robocal compensate`` prints it."""
        return self._report

    def to_csv(self) -> str:
        """The compensated program as ``robocal compensate --out`` writes it (deg, mm)."""
        return self._csv

    def to_json(self) -> str:
        """The JSON report as ``robocal compensate --json`` writes it."""
        return self._json

    def __repr__(self) -> str:
        return f"robocal.Compensation({int(self.reached.sum())} of {len(self.reached)} targets reached)"


def compensate(
    model: Model,
    nominal: Model,
    targets: Any,
    *,
    seeds: Any = None,
    marker: Optional[int] = None,
    position_only: bool = False,
    frame: str = "measuring",
    max_joint_change_deg: float = 10.0,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
) -> Compensation:
    """The joints to send a controller computing with ``nominal`` so that ``model`` (the
    calibrated robot) reaches each target, as ``robocal compensate`` solves them."""
    flags = {
        "marker": marker,
        "position_only": position_only,
        "frame": frame,
        "max_joint_change_deg": float(max_joint_change_deg),
        "joint_unit": joint_unit,
        "length_unit": length_unit,
    }
    if isinstance(targets, (str, os.PathLike)):
        return Compensation(_compensate(model, nominal, flags, file=os.fspath(targets)))
    array = np.ascontiguousarray(targets, dtype=np.float64)
    start = None if seeds is None else np.ascontiguousarray(seeds, dtype=np.float64)
    return Compensation(_compensate(model, nominal, flags, targets=array, seeds=start))


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
