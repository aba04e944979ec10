"""The Python package against the command line built from the same crate: the same numbers,
the same reports, the same errors."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import robocal

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
DATA = EXAMPLES / "puma560-measurements.csv"
VALIDATION = EXAMPLES / "puma560-validation.csv"
NOISE = ["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.02"]


def cli() -> Path:
    """The command built from this crate (`cargo build` or `cargo test` makes it)."""
    path = Path(os.environ.get("ROBOCAL_BIN", ROOT / "target" / "debug" / "robocal"))
    if not path.exists():
        pytest.fail(f"{path}: build the command first (cargo build), or set ROBOCAL_BIN")
    return path


def run_cli(*args: str) -> str:
    done = subprocess.run([str(cli()), *args], cwd=ROOT, capture_output=True, text=True, check=True)
    return done.stdout


def assert_same(ours: Any, theirs: Any, where: str = "", ignore: frozenset[str] = frozenset()) -> None:
    """Equal structures, numbers within 1e-12 (relative above 1); keys in `ignore` not compared."""
    if isinstance(theirs, dict):
        assert isinstance(ours, dict) and ours.keys() == theirs.keys(), where
        for key in theirs.keys() - ignore:
            assert_same(ours[key], theirs[key], f"{where}.{key}", ignore)
    elif isinstance(theirs, list):
        assert isinstance(ours, list) and len(ours) == len(theirs), where
        for i, (a, b) in enumerate(zip(ours, theirs)):
            assert_same(a, b, f"{where}[{i}]", ignore)
    elif isinstance(theirs, float) and not isinstance(ours, str):
        assert math.isclose(ours, theirs, rel_tol=1e-12, abs_tol=1e-12), f"{where}: {ours} != {theirs}"
    else:
        assert ours == theirs, f"{where}: {ours!r} != {theirs!r}"


def table(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The joints (deg) and markers (mm) of a marker file with a units line and a header."""
    values = np.loadtxt(path, delimiter=",", comments="#", skiprows=2)
    return values[:, :6], values[:, 6:]


@pytest.fixture(scope="module")
def puma() -> robocal.Model:
    return robocal.Model.preset("puma560")


def test_fk_is_the_papers_ready_pose_and_fk_batch_is_fk_row_by_row(puma: robocal.Model) -> None:
    ready = np.array([0.0, math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(puma.fk(ready)[:3, 3], [70.3, -150.05, 1013.6], atol=1e-9)
    q = np.random.default_rng(7).uniform(-3.0, 3.0, size=(200, 6))
    batch = puma.fk_batch(q)
    assert batch.shape == (200, 4, 4)
    for i in range(len(q)):
        assert np.array_equal(batch[i], puma.fk(q[i]))
    # A strided (not contiguous) array gives the same.
    wide = np.zeros((200, 12))
    wide[:, ::2] = q
    assert np.array_equal(puma.fk_batch(wide[:, ::2]), batch)
    assert puma.jacobian(ready).shape == (6, 6)


def test_the_jacobian_is_the_derivative_of_fk(puma: robocal.Model) -> None:
    q = np.array([0.3, 1.1, -0.7, 0.4, 0.9, -0.2])
    j = puma.jacobian(q)
    h = 1e-6
    for k in range(6):
        dq = np.zeros(6)
        dq[k] = h
        dp = (puma.fk(q + dq)[:3, 3] - puma.fk(q - dq)[:3, 3]) / (2 * h)
        np.testing.assert_allclose(j[:3, k], dp, rtol=1e-6, atol=1e-6)


def test_a_model_goes_through_toml_and_urdf_unchanged(puma: robocal.Model, tmp_path: Path) -> None:
    q = np.random.default_rng(1).uniform(-2.0, 2.0, size=(20, 6))
    again = robocal.Model.from_toml(puma.to_toml())
    assert np.array_equal(again.fk_batch(q), puma.fk_batch(q))
    assert again.joint_names == puma.joint_names == ["j1", "j2", "j3", "j4", "j5", "j6"]
    urdf = tmp_path / "puma.urdf"
    urdf.write_text(puma.to_urdf())
    from_urdf = robocal.Model.from_urdf(str(urdf))
    np.testing.assert_allclose(from_urdf.fk_batch(q)[:, :3, 3], puma.fk_batch(q)[:, :3, 3], atol=1e-6)
    assert "puma560" in robocal.presets()


def test_calibrate_from_a_file_is_the_command_lines_report(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    text = run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--validate", str(VALIDATION),
                   *NOISE, "--json", str(out), "--quiet")
    c = robocal.calibrate(puma, DATA, validate=[VALIDATION], joint_sigma=[0.007] * 3 + [0.002] * 3,
                          sigma=0.02, joint_unit="deg", length_unit="mm")
    assert_same(json.loads(c.to_json()), json.loads(out.read_text()))
    assert c.report() == text
    assert c.sets == ["training", str(VALIDATION)]


def test_calibrate_from_arrays_is_the_command_lines_report(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--validate", str(VALIDATION), *NOISE,
            "--json", str(out), "--quiet")
    joints, markers = table(DATA)
    held_joints, held_markers = table(VALIDATION)
    # In radians and metres, the defaults for arrays; the noise in the same units.
    c = robocal.calibrate(puma, np.radians(joints), markers / 1000.0,
                          validate=[(np.radians(held_joints), held_markers / 1000.0)],
                          joint_sigma=np.radians([0.007] * 3 + [0.002] * 3), sigma=0.02 / 1000.0)
    ours = c.to_json().replace('"arrays"', json.dumps(str(DATA))).replace('"validate[0]"', json.dumps(str(VALIDATION)))
    theirs = json.loads(out.read_text())
    # Degrees to radians and back, and metres, move the last digits only.
    close(json.loads(ours), theirs, 1e-6)
    # In the file's own units the numbers are the file's, and the report the same to 1e-12.
    c = robocal.calibrate(puma, joints, markers, validate=[(held_joints, held_markers)],
                          joint_sigma=[0.007] * 3 + [0.002] * 3, sigma=0.02, joint_unit="deg", length_unit="mm")
    ours = c.to_json().replace('"arrays"', json.dumps(str(DATA))).replace('"validate[0]"', json.dumps(str(VALIDATION)))
    # Rows of arrays are numbered from the table's header (line 1), not the file's.
    assert_same(json.loads(ours), theirs, ignore=frozenset({"line"}))
    p = c.parameters
    assert len(p.names) == len(p.estimates) == len(p.standard_errors) == len(p.units)
    assert p.names == [row["name"] for row in theirs["parameters"]]
    assert c.rank == theirs["rank"] and c.held == theirs["fixed"]
    assert c.covariance.shape == (len(c.covariance_names),) * 2
    lines, errors = c.pose_errors()
    assert lines[0] == 2 and errors.shape == (100, 4, 3)  # 100 poses, (before, after) x 2 markers


def test_marker_data_from_python_is_the_command_lines_fit_to_1e9(puma: robocal.Model, tmp_path: Path) -> None:
    """The README's example (its nominal markers, its noise): the held-out RMS and the
    parameters from Python, read from its own attributes, are the command line's ``--json`` to
    1e-9, the data given as a file and as arrays, through the one observation fit (#23)."""
    out = tmp_path / "report.json"
    sigmas = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]
    run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--validate", str(VALIDATION),
            "--marker", "50,0,150", "--marker=-40,60,120", "--joint-sigma-deg", ",".join(map(str, sigmas)),
            "--sigma-mm", "0.01", "--json", str(out), "--quiet")
    theirs = json.loads(out.read_text())
    held_out = dict(theirs["sets"])[str(VALIDATION)]["markers"]
    options: dict[str, Any] = dict(marker=[[50.0, 0.0, 150.0], [-40.0, 60.0, 120.0]], joint_sigma=sigmas, sigma=0.01,
                                   joint_unit="deg", length_unit="mm")
    joints, markers = table(DATA)
    held_joints, held_markers = table(VALIDATION)
    from_file = robocal.calibrate(puma, DATA, validate=[VALIDATION], **options)
    from_arrays = robocal.calibrate(puma, joints, markers, validate=[(held_joints, held_markers)], **options)
    for c, held in ((from_file, str(VALIDATION)), (from_arrays, "validate[0]")):
        assert c.sets == ["training", held]
        lines, errors = c.pose_errors(held)
        assert errors.shape == (50, 4, 3) and not np.isnan(errors).any()
        # The RMS of the marker positions' errors after calibration, pose by pose.
        after = np.linalg.norm(errors[:, 2:, :], axis=2)
        assert math.isclose(math.sqrt(np.mean(after**2)), held_out[1], rel_tol=1e-9, abs_tol=1e-9)
        before = np.linalg.norm(errors[:, :2, :], axis=2)
        assert math.isclose(math.sqrt(np.mean(before**2)), held_out[0], rel_tol=1e-9, abs_tol=1e-9)
        p = c.parameters
        assert p.names == [row["name"] for row in theirs["parameters"]]
        np.testing.assert_allclose(p.estimates, [row["value"] for row in theirs["parameters"]], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(p.standard_errors, [row["std_error"] for row in theirs["parameters"]], rtol=1e-9,
                                   atol=1e-9)
        assert c.rank == theirs["rank"] and c.held == theirs["fixed"]
    assert list(from_file.pose_errors(str(VALIDATION))[0]) == [row["line"] for row in
                                                              dict(theirs["sets"])[str(VALIDATION)]["positions"][::2]]


def close(ours: Any, theirs: Any, tol: float, where: str = "") -> None:
    if isinstance(theirs, dict):
        for key in theirs:
            close(ours[key], theirs[key], tol, f"{where}.{key}")
    elif isinstance(theirs, list):
        assert len(ours) == len(theirs), where
        for i, (a, b) in enumerate(zip(ours, theirs)):
            close(a, b, tol, f"{where}[{i}]")
    elif isinstance(theirs, float):
        assert math.isclose(ours, theirs, rel_tol=tol, abs_tol=tol), f"{where}: {ours} != {theirs}"


def test_calibrate_from_a_dataframe(puma: robocal.Model) -> None:
    pd = pytest.importorskip("pandas")
    frame = pd.read_csv(DATA, comment="#")
    c = robocal.calibrate(puma, frame, joint_unit="deg", length_unit="mm")
    d = robocal.calibrate(puma, DATA)
    assert np.array_equal(c.parameters.estimates, d.parameters.estimates)
    df = c.parameters.to_pandas()
    assert list(df.index) == c.parameters.names and list(df.columns) == ["estimate", "standard_error", "unit"]


def test_calibrate_observation_files_is_the_command_lines_report(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    data = EXAMPLES / "puma560-ballbar.csv"
    run_cli("calibrate", "--model", "puma560", "--data", str(data), "--json", str(out), "--quiet")
    c = robocal.calibrate(puma, [data])
    assert_same(json.loads(c.to_json()), json.loads(out.read_text()))


def test_marker_files_with_a_tool_or_together_are_routed_as_the_command_line_does(
    puma: robocal.Model, tmp_path: Path
) -> None:
    """A marker file with a tool point, and two marker files, go to the observations' fit, as
    ``robocal calibrate`` routes them (Python ignored the tool, and refused the two files)."""
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--tool", "0,0,100", "--json", str(out), "--quiet")
    assert_same(json.loads(robocal.calibrate(puma, DATA, tool=[0.0, 0.0, 100.0]).to_json()), json.loads(out.read_text()))
    run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--data", str(VALIDATION), "--json", str(out),
            "--quiet")
    assert_same(json.loads(robocal.calibrate(puma, [DATA, VALIDATION]).to_json()), json.loads(out.read_text()))


def test_bad_data_is_an_input_error_naming_file_line_and_column(puma: robocal.Model, tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    lines = DATA.read_text().splitlines()
    cells = lines[4].split(",")
    cells[6] = "oops"
    lines[4] = ",".join(cells)
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, bad)
    assert (e.value.file, e.value.line, e.value.field) == (str(bad), 5, "x1")
    assert "line 5" in str(e.value) and "`oops` is not a number" in str(e.value)
    # An array's NaN names its row's line in the table it makes (header on line 1).
    joints, markers = table(DATA)
    markers[2, 1] = np.nan
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, joints, markers, joint_unit="deg", length_unit="mm")
    assert (e.value.line, e.value.field) == (4, "y1")


def test_a_bad_model_file_names_its_line_and_an_unknown_option_its_name(tmp_path: Path) -> None:
    model = tmp_path / "m.toml"
    model.write_text(robocal.Model.preset("puma560").to_toml().replace('convention = "', 'convention = "x', 1))
    with pytest.raises(robocal.InputError) as e:
        robocal.Model.from_toml(str(model))
    assert e.value.file == str(model) and e.value.line is not None and e.value.line > 0
    with pytest.raises(robocal.InputError) as e:
        robocal.Model.preset("nosuch")
    assert e.value.field == "name"
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(robocal.Model.preset("puma560"), DATA, estimator="wls")
    assert e.value.field == "estimator" and "needs the noise" in str(e.value)
    # Through the observation fit (a tool point) alike: no sigma given, no joint noise.
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(robocal.Model.preset("puma560"), DATA, estimator="wls", tool=[0.0, 0.0, 100.0])
    assert e.value.field == "estimator" and "needs the noise" in str(e.value)


def test_too_few_poses_is_an_estimation_error(puma: robocal.Model) -> None:
    joints, markers = table(DATA)
    with pytest.raises(robocal.EstimationError) as e:
        robocal.calibrate(puma, joints[:5], markers[:5], joint_unit="deg", length_unit="mm")
    assert "5 poses give 30 equations" in str(e.value) and "measure more poses" in str(e.value)
    # Too few to place the measuring frame at all (the markers' registration), as the command says.
    with pytest.raises(robocal.EstimationError) as e:
        robocal.calibrate(puma, joints[:2], markers[:2], joint_unit="deg", length_unit="mm")
    assert "to place the measuring frame" in str(e.value)


SMALL_STUDY = """
name = "small"
description = "a small study for the tests"
robot = "puma560"
measured = "position"
parameters = "joints"
estimators = ["ols", "wls"]
iterations = 1
seed = 7
point_sets = 2
runs_per_set = 3
test_points = 50

[noise]
joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]

[errors]
offset_deg = 0.1
angle_deg = 0.05
length_mm = 0.5
redraw = "run"

[cases]
points = [12, 24]
sigma_me_mm = [0.0, 0.05]
"""


def test_simulate_gives_the_command_lines_samples(tmp_path: Path) -> None:
    study = tmp_path / "small.toml"
    study.write_text(SMALL_STUDY)
    run_cli("simulate", str(study), "--out", str(tmp_path / "out"), "--quiet", "--threads", "1")
    csv = (tmp_path / "out" / "small" / "samples.csv").read_text()
    s = robocal.simulate(str(study), threads=2)
    assert s["samples_csv"] == csv
    rows = np.genfromtxt(csv.splitlines(), delimiter=",", names=True, dtype=None, encoding=None)
    assert np.array_equal(s["e_p_mean_mm"][:, 1], rows["wls_e_p_mean_mm"])
    assert np.array_equal(s["de_percent"][:, 0], rows["de_wls_percent"])
    assert s["estimators"] == ["ols", "wls"] and len(s["run"]) == 2 * 2 * 2 * 3


def test_evaluate_scores_a_calibrated_model_as_the_command_line_does(puma: robocal.Model, tmp_path: Path) -> None:
    c = robocal.calibrate(puma, DATA)
    model = tmp_path / "calibrated.toml"
    model.write_text(c.model_toml())
    out = tmp_path / "evaluation.json"
    run_cli("evaluate", "--model", str(model), "--data", str(VALIDATION), "--json", str(out), "--quiet")
    theirs = json.loads(out.read_text())["observations"][0][1]
    # The model read back from its file brings its markers, and is scored as the command line
    # scores it.
    assert_same(robocal.evaluate(robocal.Model.from_toml(str(model)), VALIDATION), theirs)
    # The model in memory: its file holds angles in degrees, whose round trip moves the last
    # digits.
    close(robocal.evaluate(c.model, VALIDATION), theirs, 1e-9)


def test_observability_and_plan_are_the_command_lines(puma: robocal.Model, tmp_path: Path) -> None:
    planned = tmp_path / "planned.csv"
    run_cli("plan", "--model", "puma560", "--points", "12", "--candidates", "300", "--seed", "3",
            "--out", str(planned), "--quiet")
    p = robocal.plan(puma, 12, candidates=300, seed=3)
    rows = [line for line in planned.read_text().splitlines() if not line.startswith("#")]
    assert [line for line in p["csv"].splitlines() if not line.startswith("#")] == rows
    assert p["joints"].shape == (12, 6) and p["value"] >= p["initial"]
    text = run_cli("observability", "--model", "puma560", str(planned), "--quiet")
    o = robocal.observability(puma, p["joints"])
    assert o["report"].replace("poses", "") == text.replace(str(planned), "").replace("poses", "")
    assert o["scaled"]["rank"] == o["identifiable"] and o["whitened"] is None
    assert len(o["scaled"]["singular_values"]) == o["identifiable"]


def test_the_readmes_python_example_prints_what_the_readme_shows() -> None:
    pytest.importorskip("pandas")
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## From Python") :]
    code = section[section.index("```python\n") + 10 :]
    code = code[: code.index("```")]
    shown = section[section.index("```text\n") + 8 :]
    shown = shown[: shown.index("```")]
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert done.stdout == shown


TRUE = EXAMPLES / "puma560-true.toml"


def test_compensate_gives_the_command_lines_program(puma: robocal.Model, tmp_path: Path) -> None:
    out, report = tmp_path / "program.csv", tmp_path / "program.json"
    text = run_cli("compensate", str(VALIDATION), "--model", str(TRUE), "--nominal", "puma560", "--frame", "base",
                   "--out", str(out), "--json", str(report))
    real = robocal.Model.from_toml(str(TRUE))
    c = robocal.compensate(real, puma, VALIDATION, frame="base")
    assert c.report() == text.replace(f"wrote {out}\n", "")
    theirs = json.loads(report.read_text())
    assert_same(json.loads(c.to_json()), theirs)
    assert [row for row in c.to_csv().splitlines() if not row.startswith("#")] == [
        row for row in out.read_text().splitlines() if not row.startswith("#")
    ]
    # The arrays, target by target: the joints in rad against the JSON's degrees.
    targets = theirs["targets"]
    assert list(c.lines) == [t["line"] for t in targets]
    assert list(c.reached) == [t["reached"] for t in targets] and 0 < c.reached.sum() < len(targets)
    for i, t in enumerate(targets):
        if t["reached"]:
            np.testing.assert_allclose(np.degrees(c.joints[i]), t["joints"], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(np.degrees(c.change[i]), t["change"], rtol=1e-12, atol=1e-12)
            assert math.isclose(c.error_mm[i], t["error_mm"], rel_tol=1e-12, abs_tol=1e-15)
            assert c.iterations[i] == t["iterations"] and c.reasons[i] is None
        else:
            assert np.isnan(c.joints[i]).all() and c.reasons[i] == t["reason"]
    # The same joint targets as an array (rad): the same joints.
    joints, _ = table(VALIDATION)
    a = robocal.compensate(real, puma, np.radians(joints), frame="base")
    assert np.array_equal(a.reached, c.reached)
    np.testing.assert_allclose(a.joints[a.reached], c.joints[c.reached], rtol=1e-12, atol=1e-12)


def test_compensated_pose_and_position_targets_are_reached_by_the_real_robot(puma: robocal.Model) -> None:
    # The true robot on the nominal's base (the identity), so that every frame is the base's.
    text = TRUE.read_text()
    real = robocal.Model.from_toml(text[: text.index("[base]")] + text[text.index("[tool]") :])
    joints, _ = table(VALIDATION)
    q = np.radians(joints[:20])
    # Pose targets, the nominal poses at q, seeded at q: the joint targets' solutions, to the
    # solver's tolerance.
    poses = puma.fk_batch(q)
    by_joints = robocal.compensate(real, puma, q)
    by_poses = robocal.compensate(real, puma, poses, seeds=q)
    assert np.array_equal(by_poses.reached, by_joints.reached) and by_poses.reached.sum() >= 15
    ok = by_poses.reached
    np.testing.assert_allclose(by_poses.joints[ok], by_joints.joints[ok], atol=1e-9)
    # The real robot at the compensated joints is at the targets; at the seeds it is not.
    reached = real.fk_batch(by_poses.joints[ok])
    np.testing.assert_allclose(reached[:, :3, 3], poses[ok, :3, 3], atol=1e-8)
    np.testing.assert_allclose(reached[:, :3, :3], poses[ok, :3, :3], atol=1e-10)
    assert np.all(by_poses.before_mm[ok] > 0.1)
    # Positions only: the positions are reached, whatever the orientation.
    moved = robocal.compensate(real, puma, poses[:, :3, 3], seeds=q, position_only=True)
    ok = moved.reached
    assert ok.sum() >= 15 and np.all(moved.error_deg[ok] == 0.0)
    np.testing.assert_allclose(real.fk_batch(moved.joints[ok])[:, :3, 3], poses[ok, :3, 3], atol=1e-8)
    with pytest.raises(robocal.InputError) as e:
        robocal.compensate(real, puma, poses[:, :3, 3], seeds=q)
    assert e.value.field == "targets"
    with pytest.raises(robocal.InputError) as e:
        robocal.compensate(real, puma, poses)
    assert e.value.field == "seeds"
    with pytest.raises(robocal.InputError) as e:
        robocal.compensate(real, puma, q, marker=7)
    assert e.value.field == "marker" and "7" in str(e.value)


BALLBAR = EXAMPLES / "puma560-ballbar.csv"
CAMERA = EXAMPLES / "puma560-camera.csv"


def rows(path: Path) -> np.ndarray:
    """The rows of an observation file (units line and header skipped), as text cells."""
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")][1:]
    return np.array([line.split(",") for line in lines])


def as_files(report: str, paths: list[Path]) -> Any:
    """A JSON report of observations named by their files' stems, named by the files (stems that
    are no other string of the report: not `coordinates`, a group's name)."""
    report = report.replace(json.dumps(", ".join(p.stem for p in paths)), json.dumps(", ".join(map(str, paths))))
    for path in paths:
        report = report.replace(json.dumps(path.stem), json.dumps(str(path)))
    return json.loads(report)


def test_observations_from_arrays_calibrate_as_their_files(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(BALLBAR), "--data", str(CAMERA), "--json", str(out),
            "--quiet")
    ballbar, camera = rows(BALLBAR).astype(float), rows(CAMERA)
    units = {"joint_unit": "deg", "length_unit": "mm"}
    distances = robocal.PointDistances(ballbar[:, :6], ballbar[:, 6], sigma=ballbar[:, 7], name=BALLBAR.stem,
                                       **units)
    assert set(camera[:, 6]) == {"hand"}
    views = robocal.CameraViews(camera[:, :6].astype(float), camera[:, 7:13].astype(float), camera="hand",
                                name=CAMERA.stem, **units)
    c = robocal.calibrate(puma, observations=[distances, views])
    # The same numbers and lines as the files' (the units line first, then the header).
    assert_same(as_files(c.to_json(), [BALLBAR, CAMERA]), json.loads(out.read_text()))
    # A DataFrame with the file's columns reads the same.
    pd = pytest.importorskip("pandas")
    frame = pd.read_csv(BALLBAR, comment="#")
    d = robocal.calibrate(puma, observations=[robocal.Observations.from_pandas(frame, name=BALLBAR.stem, **units)])
    assert np.array_equal(d.parameters.estimates, robocal.calibrate(puma, [BALLBAR]).parameters.estimates)


def test_selection_on_observation_files_is_the_command_lines(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(BALLBAR), "--select", "bic", "--folds", "3",
            "--json", str(out), "--quiet")
    c = robocal.calibrate(puma, [BALLBAR], select="bic", folds=3)
    theirs = json.loads(out.read_text())
    assert "selection" in theirs
    assert_same(json.loads(c.to_json()), theirs)


def test_feasible_gls_on_observation_files_is_the_command_lines(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(BALLBAR), "--estimator", "fgls",
            "--json", str(out), "--quiet")
    c = robocal.calibrate(puma, [BALLBAR], estimator="fgls")
    theirs = json.loads(out.read_text())
    assert theirs["noise"] and theirs["noise_settled"] is not None, "the estimated noise is reported"
    assert_same(json.loads(c.to_json()), theirs)


def test_a_scaled_prior_on_observation_files_is_the_command_lines(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(BALLBAR), "--prior", "auto:machined",
            "--folds", "3", "--json", str(out), "--quiet")
    c = robocal.calibrate(puma, [BALLBAR], prior="auto:machined", folds=3)
    theirs = json.loads(out.read_text())
    assert theirs["prior_scale"]["preset"] == "machined"
    assert_same(json.loads(c.to_json()), theirs)


def test_per_session_zeros_are_the_command_lines(puma: robocal.Model, tmp_path: Path) -> None:
    second = EXAMPLES / "puma560-ballbar-2.csv"
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(BALLBAR), "--data", str(second),
            "--per-session", "point1.zero", "--json", str(out), "--quiet")
    c = robocal.calibrate(puma, [BALLBAR, second], per_session=["point1.zero"])
    theirs = json.loads(out.read_text())
    assert any("point1.zero@" in name for name in json.dumps(theirs).split('"')), theirs
    assert_same(json.loads(c.to_json()), theirs)
    with pytest.raises(robocal.InputError, match="two files or more"):
        robocal.calibrate(puma, [BALLBAR], per_session=["point1.zero"])


def write_table(path: Path, columns: dict[str, Any], n: int) -> None:
    """An observation file in deg and mm of named columns (n values, or one for every row):
    numbers at 17 significant digits, NaN an empty cell, text as it is."""

    def cell(v: Any) -> str:
        return v if isinstance(v, str) else "" if math.isnan(v) else repr(float(v))

    cells = [[cell(v[i] if np.ndim(v) > 0 else v) for v in columns.values()] for i in range(n)]
    lines = ["# units: joints=deg, lengths=mm", ",".join(columns), *(",".join(row) for row in cells)]
    path.write_text("\n".join(lines) + "\n")


def test_every_kind_of_observation_from_arrays_reads_as_its_file(puma: robocal.Model, tmp_path: Path) -> None:
    q = np.random.default_rng(3).uniform(-60.0, 60.0, size=(12, 6))
    tool = robocal.Model.from_toml(str(TRUE)).fk_batch(np.radians(q))
    xyz, r = tool[:, :3, 3], tool[:, :3, :3]
    rpy = np.degrees(np.stack([np.arctan2(r[:, 2, 1], r[:, 2, 2]), -np.arcsin(r[:, 2, 0]),
                               np.arctan2(r[:, 1, 0], r[:, 0, 0])], axis=1))
    pair = np.linalg.norm(xyz[:6] - xyz[6:], axis=1)
    point = np.linalg.norm(xyz - [500.0, 0.0, 0.0], axis=1)
    y = np.where(np.arange(12) % 3 == 0, np.nan, xyz[:, 1])
    joints = {j: q[:, k] for k, j in enumerate(puma.joint_names)}
    units = {"joint_unit": "deg", "length_unit": "mm"}
    kinds: list[tuple[robocal.Observations, dict[str, Any]]] = [
        (robocal.PairDistances(q[:6], q[6:], pair, sigma=0.02, name="pairs", **units),
         {**{j: v[:6] for j, v in joints.items()}, **{f"{j}_b": v[6:] for j, v in joints.items()},
          "distance": pair, "sigma": 0.02}),
        (robocal.PointDistances(q, point, point=[1, 2] * 6, name="points", **units),
         {**joints, "distance": point, "point": np.array([1, 2] * 6)}),
        (robocal.Coordinates(q, x=xyz[:, 0], y=y, z=xyz[:, 2], name="xyz", **units),
         {**joints, "x": xyz[:, 0], "y": y, "z": xyz[:, 2]}),
        (robocal.PlaneContacts(q, [1, 2, 3] * 4, sigma=np.full(12, 0.03), name="touches", **units),
         {**joints, "plane": np.array([1, 2, 3] * 4), "sigma": 0.03}),
        (robocal.CameraViews(q, np.hstack([xyz, rpy]), camera="world", sigma_angle=0.2, name="camera", **units),
         {**joints, **{c: v for c, v in zip(["x", "y", "z", "roll", "pitch", "yaw"], np.hstack([xyz, rpy]).T)},
          "sigma_angle": 0.2, "camera": "world"}),
    ]
    paths = []
    for observations, columns in kinds:
        path = tmp_path / f"{observations.name}.csv"
        write_table(path, columns, 6 if observations.name == "pairs" else 12)
        paths.append(path)
        # Scored as they stand (the set-up fitted: pairs have none, and are calibrated below):
        # the same numbers, the same lines.
        if observations.name != "pairs":
            assert robocal.evaluate(puma, observations) == robocal.evaluate(puma, path), observations.name
    # The distances and coordinates of the true robot calibrate the nominal one, arrays and files
    # alike (the sessions named as the files).
    from_files = robocal.calibrate(puma, observations=paths[:3])
    from_arrays = robocal.calibrate(puma, observations=[o for o, _ in kinds[:3]])
    assert_same(as_files(from_arrays.to_json(), paths[:3]), json.loads(from_files.to_json()))
    assert from_arrays.parameters.names == from_files.parameters.names


def test_calibrate_tree_is_the_command_lines_report(tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    urdf, views, held = ROOT / "presets" / "torso.urdf", EXAMPLES / "torso" / "views.csv", EXAMPLES / "torso" / "views-2.csv"
    text = run_cli("calibrate", "--model", str(urdf), "--data", str(views), "--validate", str(held), "--json", str(out),
                   "--quiet")
    c = robocal.calibrate_tree(urdf, [views], validate=[held])
    assert c.report() == text
    assert_same(json.loads(c.to_json()), json.loads(out.read_text()))
    assert sorted(c.branches) == ["head_camera", "l_hand", "r_hand"] and c.rank > 0
    assert c.branches["l_hand"].joint_names[0] == "torso" and c.branches["l_hand"].dof == 7
    with pytest.raises(robocal.InputError):
        c.model
    pd = pytest.importorskip("pandas")
    frame = pd.read_csv(views, comment="#")
    d = robocal.calibrate_tree(urdf, [frame], joint_unit="deg", length_unit="mm")
    assert np.array_equal(d.parameters.estimates, robocal.calibrate_tree(urdf, [views]).parameters.estimates)


def test_a_trees_per_session_placements_are_the_command_lines(tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    urdf, views, held = ROOT / "presets" / "torso.urdf", EXAMPLES / "torso" / "views.csv", EXAMPLES / "torso" / "views-2.csv"
    text = run_cli("calibrate", "--model", str(urdf), "--data", str(views), "--data", str(held), "--per-session",
                   "target.l_hand.*", "--validate", str(held), "--json", str(out), "--quiet")
    c = robocal.calibrate_tree(urdf, [views, held], validate=[held], per_session=["target.l_hand.*"])
    assert "target.l_hand@views-2" in text and c.report() == text
    assert_same(json.loads(c.to_json()), json.loads(out.read_text()))
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate_tree(urdf, [views], per_session=["target.l_hand.*"])
    assert e.value.field == "per_session"


def test_a_trees_cross_validation_is_the_command_lines(tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    urdf, views = ROOT / "presets" / "torso.urdf", EXAMPLES / "torso" / "views.csv"
    text = run_cli("calibrate", "--model", str(urdf), "--data", str(views), "--folds", "3", "--json", str(out),
                   "--quiet")
    c = robocal.calibrate_tree(urdf, [views], folds=3)
    assert "3-fold cross-validation" in text and c.report() == text
    assert_same(json.loads(c.to_json()), json.loads(out.read_text()))


def test_a_trees_fgls_and_selection_are_the_command_lines(tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    urdf, views = ROOT / "presets" / "torso.urdf", EXAMPLES / "torso" / "views.csv"
    fgls, bic = robocal.calibrate_tree(urdf, [views], estimator="fgls"), robocal.calibrate_tree(urdf, [views], select="bic")
    for flags, c in [(["--estimator", "fgls"], fgls), (["--select", "bic"], bic)]:
        text = run_cli("calibrate", "--model", str(urdf), "--data", str(views), *flags, "--json", str(out), "--quiet")
        assert c.report() == text
        assert_same(json.loads(c.to_json()), json.loads(out.read_text()))


def test_evaluate_whitens_an_observation_file_as_the_command_line_does(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "evaluation.json"
    sigmas = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]
    run_cli("evaluate", "--model", "puma560", "--data", str(BALLBAR), "--joint-sigma-deg", ",".join(map(str, sigmas)),
            "--json", str(out), "--quiet")
    theirs = json.loads(out.read_text())["observations"][0][1]
    ours = robocal.evaluate(puma, BALLBAR, joint_sigma=sigmas, joint_unit="deg", length_unit="mm")
    assert_same(ours, theirs)
    assert ours != robocal.evaluate(puma, BALLBAR), "the joint noise changes the whitened residuals"
    # sigma is for rows without their own (the ball bar has its column: unchanged); a noise file
    # of the same joint sigmas is the same noise, as the command line reads it.
    with_sigma = robocal.evaluate(puma, BALLBAR, joint_sigma=sigmas, sigma=0.5, joint_unit="deg", length_unit="mm")
    assert_same(with_sigma, theirs)
    noise = tmp_path / "noise.toml"
    noise.write_text(f"joint_sigma = {sigmas}\n")
    run_cli("evaluate", "--model", "puma560", "--data", str(BALLBAR), "--noise", str(noise), "--json", str(out),
            "--quiet")
    assert_same(robocal.evaluate(puma, BALLBAR, noise=str(noise)), json.loads(out.read_text())["observations"][0][1])
    assert_same(robocal.evaluate(puma, BALLBAR, noise=str(noise)), theirs)


def test_evaluate_tree_scores_views_as_the_command_line_does(tmp_path: Path) -> None:
    out = tmp_path / "evaluation.json"
    urdf, views = ROOT / "presets" / "torso.urdf", EXAMPLES / "torso" / "views.csv"
    tips = ["head_camera", "l_hand", "r_hand"]
    run_cli("evaluate", "--model", str(urdf), "--tips", ",".join(tips), "--data", str(views), "--joint-sigma-deg", "0.05",
            "--json", str(out), "--quiet")
    theirs = json.loads(out.read_text())["observations"][0][1]
    ours = robocal.evaluate_tree(urdf, views, tips=tips, joint_sigma=[0.05], joint_unit="deg", length_unit="mm")
    assert_same(ours, theirs)
    assert len(ours["views"]) == 120


def test_evaluate_tree_scores_written_branches_as_the_command_line_does(tmp_path: Path) -> None:
    out, branches = tmp_path / "evaluation.json", tmp_path / "branches"
    urdf, views, held = ROOT / "presets" / "torso.urdf", EXAMPLES / "torso" / "views.csv", EXAMPLES / "torso" / "views-2.csv"
    tips = ["head_camera", "l_hand", "r_hand"]
    run_cli("calibrate", "--model", str(urdf), "--tips", ",".join(tips), "--data", str(views), "--out-dir", str(branches),
            "--quiet")
    run_cli("evaluate", "--model", str(urdf), "--branches", str(branches), "--data", str(held), "--json", str(out),
            "--quiet")
    theirs = json.loads(out.read_text())["observations"][0][1]
    ours = robocal.evaluate_tree(urdf, held, tips=tips, branches=branches, joint_unit="deg", length_unit="mm")
    assert_same(ours, theirs)
    nominal = robocal.evaluate_tree(urdf, held, tips=tips, joint_unit="deg", length_unit="mm")
    assert ours["view_position"][1] < nominal["view_position"][1]
    # A branch of another robot is refused, naming its file.
    (branches / "head_camera.toml").write_text((EXAMPLES / "puma560-true.toml").read_text())
    with pytest.raises(robocal.InputError) as e:
        robocal.evaluate_tree(urdf, held, tips=tips, branches=branches, joint_unit="deg", length_unit="mm")
    assert e.value.file is not None and e.value.file.endswith("head_camera.toml")
    assert "joints, the branch to head_camera has" in str(e.value)


def test_priors_given_as_a_list_are_repeated_prior_flags(puma: robocal.Model, tmp_path: Path) -> None:
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--prior", "j2.theta=0.01deg",
            "--prior", "j3.theta=0.02deg", "--json", str(out), "--quiet")
    ours = robocal.calibrate(puma, DATA, prior=["j2.theta=0.01deg", "j3.theta=0.02deg"])
    assert_same(json.loads(ours.to_json()), json.loads(out.read_text()))
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, DATA, prior=["auto", "auto:machined"])
    assert e.value.field == "prior" and "give it once" in str(e.value)


def test_sessions_of_one_name_are_refused(puma: robocal.Model, tmp_path: Path) -> None:
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "ballbar.csv").write_text(BALLBAR.read_text())
    files = [tmp_path / "a" / "ballbar.csv", tmp_path / "b" / "ballbar.csv"]
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, files, per_session=["point1.zero"])
    assert e.value.field == "per_session" and "`ballbar`" in str(e.value)


def test_marker_options_with_a_ball_bar_are_the_command_lines(puma: robocal.Model, tmp_path: Path) -> None:
    """use_markers, fixed_markers, fixed_base and sigma on a marker file fitted with a ball
    bar: the command line's report, number for number."""
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--data", str(BALLBAR), "--tool", "50,0,150",
            "--marker", "50,0,150", "--marker=-40,60,120", "--markers", "2", "--fixed-markers",
            "--sigma-mm", "0.05", "--json", str(out), "--quiet")
    ours = robocal.calibrate(puma, [DATA, BALLBAR], tool=[50.0, 0.0, 150.0],
                             marker=[[50.0, 0.0, 150.0], [-40.0, 60.0, 120.0]], use_markers=[2],
                             fixed_markers=True, sigma=0.05, joint_unit="deg", length_unit="mm")
    report = json.loads(ours.to_json())
    assert not any(p["name"].startswith("marker") for p in report["parameters"])
    assert_same(report, json.loads(out.read_text()))
    # Noise files (joint noise and sigma_me; a laser tracker's covariance), as the command reads them.
    for noise in (EXAMPLES / "puma560-noise.toml", EXAMPLES / "noise" / "laser-tracker-0.1mm.toml"):
        run_cli("calibrate", "--model", "puma560", "--data", str(DATA), "--data", str(BALLBAR), "--tool",
                "50,0,150", "--noise", str(noise), "--json", str(out), "--quiet")
        ours = robocal.calibrate(puma, [DATA, BALLBAR], tool=[50.0, 0.0, 150.0], noise=str(noise),
                                 joint_unit="deg", length_unit="mm")
        assert_same(json.loads(ours.to_json()), json.loads(out.read_text()))


def _quaternion(r: np.ndarray) -> tuple[float, float, float, float]:
    """The unit quaternion (w, x, y, z) of the rotation matrix ``r`` (Shepperd's method)."""
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2.0
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2.0, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2.0, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2.0, r[1, 0] - r[0, 1])
    return w, x, y, z


def test_a_probe_file_with_a_ball_bar_is_the_command_line(puma: robocal.Model, tmp_path: Path) -> None:
    """A 6-DOF probe's file (marker 1 and a quaternion) of the example's true robot, fitted
    with the example's ball bar: Python's report is the command line's, number for number, and
    the probe's orientation is among the residuals."""
    true = (EXAMPLES / "puma560-true.toml").read_text()
    true = true.replace("[tool]\nxyz_mm = [52.0, 1.0, 148.0]", "[tool]\nxyz_mm = [60.0, 5.0, 140.0]\nrpy_deg = [11.0, -6.0, 17.0]")
    truth = robocal.Model.from_toml(true)
    rng = np.random.default_rng(7)
    rows = ["# units: joints=deg, lengths=mm", "j1,j2,j3,j4,j5,j6,x1,y1,z1,qw,qx,qy,qz"]
    for _ in range(60):
        q = rng.uniform(-1.5, 1.5, 6)
        t = truth.fk(q)
        cells = [*np.degrees(q), *t[:3, 3], *_quaternion(t[:3, :3])]
        rows.append(",".join(f"{c:.12f}" for c in cells))
    probe = tmp_path / "probe.csv"
    probe.write_text("\n".join(rows) + "\n")
    out = tmp_path / "report.json"
    run_cli("calibrate", "--model", "puma560", "--data", str(probe), "--data", str(BALLBAR),
            "--marker", "60,5,140", "--json", str(out), "--quiet")
    ours = robocal.calibrate(puma, [probe, BALLBAR], marker=[[60.0, 5.0, 140.0]], joint_unit="deg", length_unit="mm")
    report = json.loads(ours.to_json())
    assert any(p["name"] == "marker1.rz" for p in report["parameters"])
    assert any(o["kind"] == "probe rz" for o in report["sets"][0][1]["observations"])
    assert_same(report, json.loads(out.read_text()))


def test_what_the_command_line_refuses_python_refuses(puma: robocal.Model) -> None:
    """The command line's refusals of options that observation files cannot honour, of
    standard deviations out of range, and of counts, as InputErrors naming the field."""
    refused: list[tuple[dict[str, Any], str]] = [
        (dict(use_markers=[1]), "use_markers"),
        (dict(params="all", fixed_base=True), "params"),
        (dict(marker=[[0.0, 0.0, 0.0]]), "marker"),
        (dict(tool=[float("nan"), 0.0, 0.0]), "tool"),
        (dict(joint_sigma=[-0.01]), "joint_sigma"),
        (dict(folds=-1), "folds"),
        (dict(iterations=10**9), "iterations"),
    ]
    for options, field in refused:
        with pytest.raises(robocal.InputError) as e:
            robocal.calibrate(puma, observations=[BALLBAR], joint_unit="deg", length_unit="mm", **options)
        assert e.value.field == field, (options, str(e.value))
    # A zero measurement sigma is none, as the command's default --sigma-mm 0.
    zero = robocal.calibrate(puma, DATA, sigma=0.0).to_json()
    assert zero == robocal.calibrate(puma, DATA).to_json()
    # A robust loss and fgls do not go together; the squared loss is fgls's own.
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, [BALLBAR], estimator="fgls", loss="huber")
    assert e.value.field == "loss"
    squared = robocal.calibrate(puma, [BALLBAR], estimator="fgls", loss="squared").to_json()
    assert squared == robocal.calibrate(puma, [BALLBAR], estimator="fgls").to_json()
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, [BALLBAR], folds=10000)
    assert e.value.field == "folds" and "10000 folds for" in str(e.value)
    # params as --params reads it: comma-separated names, a set's word alone, not nothing.
    for params, words in ((["joints", "j1.a"], "is a parameter set"), ([], "expected joints, all")):
        with pytest.raises(robocal.InputError) as e:
            robocal.calibrate(puma, DATA, params=params)
        assert e.value.field == "params" and words in str(e.value), str(e.value)
    named = robocal.calibrate(puma, DATA, params="j2.a, j3.a")
    assert {"j2.a", "j3.a"} <= set(named.parameters.names)
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, DATA, noise=EXAMPLES / "puma560-noise.toml", sigma=0.01)
    assert e.value.field == "sigma" and "noise gives the measurement noise too" in str(e.value)


def test_bad_observations_are_input_errors_naming_their_row_and_column(puma: robocal.Model) -> None:
    q = np.zeros((3, 6))
    bad = robocal.PointDistances(q, [0.5, -0.2, 0.4], name="bar")
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, observations=[bad])
    # The units line is line 1 and the header line 2: the second row is line 4.
    assert (e.value.line, e.value.field) == (4, "distance") and "bar" in str(e.value)
    with pytest.raises(robocal.InputError) as e:
        robocal.PointDistances(q, [0.5, 0.2], name="bar")
    assert e.value.field == "distance"
    with pytest.raises(robocal.InputError) as e:
        robocal.calibrate(puma, observations=[robocal.CameraViews(q, np.zeros((3, 6)), camera="nowhere")])
    assert e.value.field == "camera"
