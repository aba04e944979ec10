"""robocal: kinematic calibration of robot arms, from Python (typed stub).

A thin layer over the Rust library: every number is computed by it, every file read by its
readers, and the reports are the command line's. Units inside are millimetres and radians
(millimetres for prismatic joints).
"""

import os
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, os.PathLike[str]]
FloatArray = npt.NDArray[np.float64]

class RobocalError(Exception):
    """An error of robocal: the whole message, and the file, line and field it names."""

    message: str
    file: Optional[str]
    line: Optional[int]
    field: Optional[str]
    def __init__(
        self, message: str, file: Optional[str] = None, line: Optional[int] = None, field: Optional[str] = None
    ) -> None: ...

class InputError(RobocalError, ValueError):
    """What was given cannot be used: a file (with its line and column), an array, an option."""

class EstimationError(RobocalError):
    """The data cannot make the calibration asked for (too few poses, nothing identifiable)."""

class Model:
    """A robot model (DH with Hayati's beta, or a URDF chain), its kinematics compiled once."""

    @staticmethod
    def preset(name: str) -> Model:
        """A preset by name (``presets()``): ``puma560``, ``ur5e``, ..."""
    @staticmethod
    def from_toml(path_or_text: str) -> Model:
        """A model from a TOML file, or from TOML text (text holds a newline or ``=``)."""
    @staticmethod
    def from_urdf(path: str, base_link: Optional[str] = None, tip_link: Optional[str] = None) -> Model:
        """The chain of a URDF file from ``base_link`` to ``tip_link`` (default: the root link
        and the only leaf)."""
    def to_toml(self) -> str:
        """The model as TOML, as ``robocal model show`` prints it."""
    def to_urdf(self, standard: bool = False) -> str:
        """The model as URDF, as ``robocal model urdf`` writes it."""
    @property
    def name(self) -> str:
        """The model's name."""
    @property
    def joint_names(self) -> list[str]:
        """The joints' names, in order."""
    @property
    def dof(self) -> int:
        """Number of joints."""
    @property
    def parameter_names(self) -> list[str]:
        """The error parameters' names (``j1.theta``, ..., ``base.x``, ..., ``tool.x``)."""
    def fk(self, q: FloatArray) -> FloatArray:
        """The tool pose at ``q`` (rad; mm for prismatic joints): a 4 x 4 transform, mm."""
    def fk_batch(self, q: FloatArray) -> FloatArray:
        """The tool poses at each row of ``q`` (n x dof): n x 4 x 4. The GIL is released; a
        C-contiguous ``q`` is read in place. Equal to ``fk`` row by row."""
    def jacobian(self, q: FloatArray) -> FloatArray:
        """The manipulator Jacobian at ``q``: 6 x dof, linear rows (mm per joint unit) then
        angular rows (rad per joint unit)."""

def presets() -> list[str]:
    """The names of the preset models."""

def studies() -> list[str]:
    """The names of the preset Monte Carlo studies."""

@dataclass(frozen=True)
class Parameters:
    """The identified parameters as the report lists them (deg for angles, mm for lengths)."""

    names: list[str]
    estimates: FloatArray
    standard_errors: FloatArray
    units: list[str]
    def to_pandas(self) -> Any:
        """A DataFrame indexed by name: estimate, standard_error, unit (needs pandas)."""

class Calibration:
    """A finished calibration."""

    @property
    def parameters(self) -> Parameters:
        """The identified parameters."""
    @property
    def covariance(self) -> FloatArray:
        """The estimate's covariance in mm and rad, rows and columns as ``covariance_names``."""
    @property
    def covariance_names(self) -> list[str]:
        """The names of the covariance's rows and columns."""
    @property
    def rank(self) -> int:
        """The numerical rank of the identified system."""
    @property
    def held(self) -> list[str]:
        """The combinations held because the poses cannot identify them, with the reason."""
    @property
    def model(self) -> Model:
        """The calibrated model."""
    @property
    def sets(self) -> list[str]:
        """The scored sets: ``training``, then each held-out set (marker data only)."""
    def pose_errors(self, set: str = "training") -> tuple[npt.NDArray[np.uint64], FloatArray]:
        """The poses' lines (in the file, or in the table the arrays make: header on line 1)
        and their position errors, measured minus predicted (mm): poses x (stages x markers)
        x 3, stage-major (before, after)."""
    def model_toml(self) -> str:
        """The calibrated model as TOML with its markers, as ``--out-model`` writes it."""
    def report(self) -> str:
        """The report as ``robocal calibrate`` prints it."""
    def to_json(self) -> str:
        """The JSON report as ``robocal calibrate --json`` writes it."""

def calibrate(
    model: Model,
    joints: Any,
    markers: Any = None,
    *,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    estimator: Optional[str] = None,
    joint_sigma: Union[Sequence[float], FloatArray, None] = None,
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
    """Calibrate ``model`` as ``robocal calibrate`` does, with its options.

    The data: ``joints`` (n x dof) and ``markers`` (n x 3m, or n x m x 3) arrays, with
    ``pose_sigma`` (n) and ``orientations`` (n x 4, qw qx qy qz) if measured; or a pandas
    DataFrame with a file's columns (``j1``..., ``x1,y1,z1``, ...); or a file's path; or a list
    of observation files' paths (distances, plane contacts, coordinates, camera views), fitted
    together. Arrays and DataFrames go through the same reader as the files.

    Units: ``joint_unit`` ``"rad"`` or ``"deg"`` and ``length_unit`` ``"m"`` or ``"mm"``, given
    together; arrays default to rad and m, files to their own units line. The options in
    units (``joint_sigma``, ``sigma``, ``sigma_orientation``, ``marker``, ``tool``) are in these
    units (rad and m when none are given).

    ``estimator``: ``ols``, ``wls``, ``wls-diag``, ``wls-sigma`` or ``fgls`` (default: wls
    with the noise, ols without); ``noise``: a noise file instead of the sigmas; ``params``:
    ``joints``, ``all``, ``offsets``, ``none`` or names and patterns (``j*.theta``);
    ``validate``: held-out sets, each ``(joints, markers)``, a DataFrame or a path; ``folds``:
    k-fold cross-validation; ``select``: ``cv``, ``bic`` or ``t``; ``prior``: ``PATTERN=SD,...``,
    a preset, or ``auto[:PRESET]``; ``loss``: ``huber:1.345`` and the like; ``use_markers``: the
    marker numbers to fit (``--markers``); ``iterations``: Gauss-Newton steps at most.

    Raises ``InputError`` for bad data or options, ``EstimationError`` when the data cannot
    make the calibration.
    """

def evaluate(
    model: Model,
    data: Any,
    markers: Any = None,
    *,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    joint_sigma: Union[Sequence[float], FloatArray, None] = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    noise: Optional[PathLike] = None,
    use_markers: Optional[Sequence[int]] = None,
) -> dict[str, Any]:
    """``model`` scored as it stands on ``data`` (as ``calibrate`` takes it: arrays, a
    DataFrame, a file), as ``robocal evaluate`` scores it: for marker data, the set pose by pose
    as its JSON has it (``pooled``: before, ``poses``, ``per_marker``; joint values in
    degrees); for an observation file, its score with the set-up fitted and the robot held. A
    model read from a file with ``[[markers]]``, or a calibration's model, brings its markers."""

def observability(
    model: Model,
    poses: FloatArray,
    *,
    params: Union[str, Sequence[str]] = "joints",
    measured: str = "position",
    joint_sigma: Union[Sequence[float], FloatArray, None] = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    joint_unit: str = "rad",
    length_unit: str = "m",
) -> dict[str, Any]:
    """The observability indices of ``poses`` (n x dof), as ``robocal observability`` gives
    them: ``scaled`` (and ``whitened`` with the noise) each with ``o1``..``o5``, ``log_det``,
    ``condition_number``, ``rank``, ``singular_values``; and ``report``, the command's text."""

def plan(
    model: Model,
    points: int,
    *,
    candidates: int = 5000,
    criterion: str = "d",
    seed: int = 1,
    params: Union[str, Sequence[str]] = "joints",
    measured: str = "position",
    joint_sigma: Union[Sequence[float], FloatArray, None] = None,
    sigma: Optional[float] = None,
    sigma_orientation: Optional[float] = None,
    joint_unit: str = "rad",
    length_unit: str = "m",
) -> dict[str, Any]:
    """``points`` poses chosen among ``candidates`` random ones to maximise ``criterion`` (d,
    o1..o5), as ``robocal plan`` chooses them with the same seed: ``joints`` (points x dof, rad
    and mm), ``value`` and ``initial`` (the criterion's), ``summary`` (the command's text) and
    ``csv`` (the pose file, degrees)."""

def simulate(
    study: str, *, threads: Optional[int] = None, noise: Optional[PathLike] = None, quiet: bool = False
) -> dict[str, Any]:
    """Run a Monte Carlo study (a preset name or a TOML file) as ``robocal simulate`` does,
    with its progress bar on a terminal (unless ``quiet``), the GIL released; ``noise``, a noise
    file, replaces the study's noise. The numbers do not depend on ``threads``. The dict holds ``name``, ``estimators``,
    ``tables`` and ``samples_csv`` (the command line's files), and per run ``n_points``,
    ``sigma_me_mm``, ``set``, ``run``, then ``e_p_mean_mm``, ``e_p_rms_mm``, ``e_p_max_mm``,
    ``e_r_mean_deg`` (runs x estimators) and ``de_percent`` (runs x compared estimators)."""

def reproduce(*, threads: Optional[int] = None, quiet: bool = False) -> list[dict[str, Any]]:
    """The paper's two studies (paper-table1, paper-table2), as ``robocal reproduce`` runs them."""
