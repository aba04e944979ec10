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
        """The calibrated model (of a chain; a tree's raises ``InputError``: see ``branches``)."""
    @property
    def branches(self) -> dict[str, Model]:
        """A tree's calibrated branches by tip link, each a chain from the root (empty for a
        chain)."""
    @property
    def sets(self) -> list[str]:
        """The scored sets, named as in the JSON report's ``sets``: ``training``, then each
        held-out set (its path, or ``validate[k]`` for arrays and DataFrames), then ``held out,
        pooled`` (with several held-out sets) and the cross-validation (``3-fold
        cross-validation``, with ``folds``); empty for a tree."""
    def pose_errors(self, set: str = "training") -> tuple[npt.NDArray[np.uint64], FloatArray]:
        """The marker positions' errors of a set (one of ``sets``) pose by pose: the poses'
        lines (in the file, or in the table the arrays make: header on line 1) and the errors,
        measured minus predicted (mm): poses x (stages x markers) x 3, stage-major (before,
        after), the markers every one the set measures (numbered from 1, in order), NaN where a
        pose's coordinate was not measured. The poses with markers only: a set without markers
        has none (shape 0 x 0 x 3); a probe's orientations and other kinds are in ``to_json()``'s
        ``sets``. Before: the base and markers fitted with the joints nominal (the report's
        ``fits``)."""
    def model_toml(self) -> str:
        """The calibrated model as TOML with its markers, as ``--out-model`` writes it (a
        chain's)."""
    def report(self) -> str:
        """The report as ``robocal calibrate`` prints it."""
    def to_json(self) -> str:
        """The JSON report as ``robocal calibrate --json`` writes it."""

class Observations:
    """Observations of one measuring session as the columns of an observation file, read by
    the library's reader (the same checks and numbers as the file's): built from arrays by
    ``PairDistances``, ``PointDistances``, ``PlaneContacts``, ``Coordinates`` and
    ``CameraViews``, or from a DataFrame by ``from_pandas``. ``name`` names the session (as a
    file's stem does); lengths are in ``length_unit`` (m or mm), angles and joint values in
    ``joint_unit`` (rad or deg): rad and m unless told."""

    name: str
    joint_unit: str
    length_unit: str
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
        """``joints`` (n x dof) and named columns of an observation file (n values, or one for
        every row; NaN an empty cell), ``joints_b`` the second poses of pairs, ``constant``
        text columns (``camera``)."""
    @classmethod
    def from_pandas(
        cls, frame: Any, *, name: str = "observations", joint_unit: str = "rad", length_unit: str = "m"
    ) -> Observations:
        """A DataFrame with an observation file's columns (the joints by name, ``distance``,
        ``point``, ``plane``, ``x``..``yaw``, ``camera``, ``sigma``, ``sigma_angle``,
        ``kind`` for several kinds)."""
    def to_csv(self, model: Model) -> str:
        """The observation file these observations make for ``model`` (its joints' names)."""

class PairDistances(Observations):
    """Distances between the tool point at two poses (a ball bar between poses, a tape)."""

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
        """``joints`` and ``joints_b`` (n x dof), ``distance`` (n), ``sigma`` (one or n;
        default 0.01 mm)."""

class PointDistances(Observations):
    """Distances from the tool point to fixed points (a ball bar's fixed ball)."""

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
        """``joints`` (n x dof), ``distance`` (n), ``point`` (the point's number 1, 2, ...: one
        or n; default 1), ``sigma`` (one or n; default 0.01 mm)."""

class PlaneContacts(Observations):
    """The tool point touching planes (signed distance 0)."""

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
        """``joints`` (n x dof), ``plane`` (the plane's number 1, 2, ...: one or n), ``sigma``
        (one or n; default 0.01 mm)."""

class Coordinates(Observations):
    """Coordinates of the tool in the measuring frame, any of them."""

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
        """``joints`` (n x dof); each coordinate given n values (NaN where not measured):
        ``x, y, z`` (length unit), ``roll, pitch, yaw`` (joint unit, ``R = Rz(yaw) Ry(pitch)
        Rx(roll)``); ``sigma`` and ``sigma_angle`` (one or n; default 0.01 mm and 0.01 deg)."""

class CameraViews(Observations):
    """A camera's views of its target: the target's pose in the camera's frame."""

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
        """``joints`` (n x dof), ``views`` (n x 6: x, y, z, roll, pitch, yaw), ``camera``
        ``hand`` (on the arm, the target fixed) or ``world`` (fixed, the target on the arm);
        ``sigma`` and ``sigma_angle`` (one or n; default 0.5 mm and 0.1 deg)."""

def calibrate(
    model: Model,
    joints: Any = None,
    markers: Any = None,
    *,
    observations: Sequence[Union[PathLike, Observations]] = (),
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
    """Calibrate ``model`` as ``robocal calibrate`` does, with its options.

    The data: ``joints`` (n x dof) and ``markers`` (n x 3m, or n x m x 3) arrays, with
    ``pose_sigma`` (n) and ``orientations`` (n x 4, qw qx qy qz) if measured; or a pandas
    DataFrame with a file's columns (``j1``..., ``x1,y1,z1``, ...); or a file's path. Or
    ``observations``: observation files' paths (distances, plane contacts, coordinates, camera
    views) and ``Observations`` (built from arrays or a DataFrame), each a session, fitted
    together (a list of them as ``joints`` too). Arrays and DataFrames go through the same
    reader as the files. Every kind, marker data and a probe's among them, is read as
    observations and fitted by the command line's one observation calibration, any mix of
    them together, each a session: the same numbers as ``robocal calibrate`` for the same
    inputs. ``sigma``, ``sigma_orientation`` or a noise file's ``sigma_me_mm`` are the sigmas of
    the rows without their own (``pose_sigma``, a ``sigma`` column), its ``[device]``'s
    covariance taken at each point measured; ``sigma`` needs no ``joint_sigma``.
    ``params`` is read as ``--params``: a list is joined by commas.

    Units: ``joint_unit`` ``"rad"`` or ``"deg"`` and ``length_unit`` ``"m"`` or ``"mm"``, given
    together; arrays default to rad and m, files to their own units line. The options in
    units (``joint_sigma``, ``sigma``, ``sigma_orientation``, ``marker``, ``tool``) are in these
    units (rad and m when none are given); ``joint_sigma`` is one per joint or one for all.

    ``estimator``: ``ols``, ``wls``, ``wls-diag``, ``wls-sigma`` or ``fgls`` (default: wls
    with the noise, ols without); ``noise``: a noise file instead of the sigmas; ``params``:
    ``joints``, ``all``, ``offsets``, ``none`` or names and patterns (``j*.theta``);
    ``validate``: held-out sets, each ``(joints, markers)``, a DataFrame or a path; ``folds``:
    k-fold cross-validation; ``select``: ``cv``, ``bic`` or ``t``; ``prior``: ``PATTERN=SD,...``,
    a preset, or ``auto[:PRESET]``, or a list of them as repeated ``--prior`` (``auto`` once);
    ``loss``: ``huber:1.345`` and the like; ``use_markers``: the
    marker numbers to fit (``--markers``); ``iterations``: solver steps at most;
    ``per_session``: set-up parameters (names and patterns, ``point1.zero``, ``point*``) one
    per observation file, each file a session named by its stem (or its ``name``): an
    instrument re-zeroed or moved between sessions (two files or more).

    Raises ``InputError`` for bad data or options, ``EstimationError`` when the data cannot
    make the calibration.
    """

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
    joint_sigma: Union[Sequence[float], FloatArray, None] = None,
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
    """Calibrate the tree of the URDF file ``urdf`` (from ``base_link``, default its only root,
    to the ``tips``, default every leaf) from camera views between its branches, as ``robocal
    calibrate --model tree.urdf --data views.csv`` does: ``views`` and ``validate`` are view
    files' paths or DataFrames with their columns (``camera``, ``target``, the joints, ``x``..
    ``yaw``, ``sigma``, ``sigma_angle``), fitted together and held out. ``estimator`` ols,
    wls (default) or fgls (the joint and view noise estimated from the residuals);
    ``joint_sigma`` one per tree joint or one for all, in ``joint_unit`` (rad unless given);
    ``params`` the joint parameters (not ``all``: the base is never seen); ``prior`` standard
    deviations or a preset; ``select`` cv, bic or t; ``folds`` k-fold cross-validation of the
    poses; ``per_session`` cameras' and targets' placements (``target.l_hand.*``) with one value
    per views file (two or more, each a session named by its file's stem).
    The result's ``branches`` are the calibrated chains; its report and JSON are the command
    line's."""

def evaluate_tree(
    urdf: PathLike,
    views: Any,
    *,
    tips: Sequence[str] = (),
    base_link: Optional[str] = None,
    branches: Optional[PathLike] = None,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
    joint_sigma: Union[Sequence[float], FloatArray, None] = None,
) -> dict[str, Any]:
    """The tree of the URDF file ``urdf`` (from ``base_link`` to the ``tips``, as
    ``calibrate_tree`` reads it) scored as it stands on ``views`` (a view file's path or a
    DataFrame of its columns), as ``robocal evaluate --model tree.urdf --tips ...`` scores it:
    its cameras and targets fitted to the views, the tree held, each view's residuals whitened
    by its sigmas and ``joint_sigma`` (one per tree joint or one for all, in ``joint_unit``).
    With ``branches`` (a folder, as ``--branches``), the tree's joints are those of the branch
    models ``calibrate --out-dir`` wrote there (``<tip>.toml`` per branch; a joint on several
    branches one geometry in every file, else an ``InputError`` naming the file): the
    calibrated tree scored on new views. The score as the command's JSON has it (``views``:
    each view's residual; ``position`` and ``rotation``: their RMS)."""

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
    DataFrame, a file, ``Observations``), as ``robocal evaluate`` scores it, the robot held:
    marker data with the model's base and markers, an observation file with its set-up fitted.
    The score as the JSON's ``observations[i][1]`` has it (``observations``, ``markers``,
    ``by_marker``, ``positions``, ``lengths``; ``before`` and ``after`` the same), its
    residuals whitened by the file's sigma column (``sigma``, ``sigma_orientation`` or a
    ``noise`` file's for rows without, its device included) and ``joint_sigma``. A
    model read from a file with ``[[markers]]``, or a calibration's model, brings its markers."""

class Compensation:
    """A compensated program, one entry per target in the order given."""

    lines: npt.NDArray[np.uint64]
    """Each target's line in its file (arrays: its row + 2, the header on line 1)."""
    reached: npt.NDArray[np.bool_]
    """Whether it is reached (within the tolerances, on the seed's branch, within the limits)."""
    joints: FloatArray
    """The joint values to send (n x dof; rad, mm for prismatic joints; NaN where unreachable)."""
    change: FloatArray
    """Their change from the seed (n x dof; rad, mm; NaN where unreachable)."""
    error_mm: FloatArray
    """The calibrated model's remaining position error (mm; NaN where unreachable)."""
    error_deg: FloatArray
    """Its remaining orientation error (deg; 0 with ``position_only``)."""
    before_mm: FloatArray
    """Its position error at the seed, uncompensated (mm)."""
    before_deg: FloatArray
    """Its orientation error at the seed (deg)."""
    iterations: npt.NDArray[np.uint64]
    """Iterations taken (0 where unreachable)."""
    reasons: list[Optional[str]]
    """Why each target cannot be reached (None where it is), as the report words it."""
    def report(self) -> str:
        """The report as ``robocal compensate`` prints it."""
    def to_csv(self) -> str:
        """The compensated program as ``robocal compensate --out`` writes it (deg, mm)."""
    def to_json(self) -> str:
        """The JSON report as ``robocal compensate --json`` writes it (deg, mm)."""

def compensate(
    model: Model,
    nominal: Model,
    targets: Any,
    *,
    seeds: Optional[FloatArray] = None,
    marker: Optional[int] = None,
    position_only: bool = False,
    frame: str = "measuring",
    max_joint_change_deg: float = 10.0,
    joint_unit: Optional[str] = None,
    length_unit: Optional[str] = None,
) -> Compensation:
    """The joints to send a controller that computes with ``nominal`` so that ``model`` (the
    calibrated robot, the joint limits its) reaches each target, as ``robocal compensate``
    solves them (damped least squares from the seed), the GIL released.

    ``targets``: joint values taught on the nominal model (n x dof, rad and mm: the target is
    the nominal pose there, and its own seed); tool poses (n x 4 x 4, mm, as ``Model.fk_batch``
    gives them) or positions (n x 3, mm, with ``position_only``), each with its row of
    ``seeds`` (n x dof), the nominal joint solution; or a target file's path (its units line,
    or ``joint_unit`` and ``length_unit``). ``marker``: the number of one of ``model``'s
    markers (a model file's ``[[markers]]``, a calibration's) to bring to the targets in place
    of the tool point; ``frame``: ``measuring`` (the calibrated base's frame) or ``base``;
    ``max_joint_change_deg``: a larger move from the seed is a branch change (unreachable)."""

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
