//! The file of a tree's camera views (see `docs/formats.md`):
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! camera,target,torso,head_pan,head_tilt,l1,...,r6,x,y,z,roll,pitch,yaw
//! head_camera,l_target,10,-5,20,...,12.5,-40.2,480.1,3.2,-1.5,88.0
//! ```
//!
//! `camera` and `target` name the branch (its tip link) each is fixed to, or `world` for one
//! fixed in the root link's frame; the joint columns are the tree's joints (every one, each
//! once; consecutive rows of the same joint values are one pose); `x, y, z` (length unit) and `roll, pitch, yaw` (the joints' angle unit,
//! `R = Rz(yaw) Ry(pitch) Rx(roll)`) the target's pose in the camera's frame. Optional `sigma`
//! (length unit) and `sigma_angle` (angle unit) per row, by default
//! [`DEFAULT_CAMERA_SIGMA_MM`](crate::calibration::kinds::DEFAULT_CAMERA_SIGMA_MM) and
//! [`DEFAULT_CAMERA_SIGMA_DEG`](crate::calibration::kinds::DEFAULT_CAMERA_SIGMA_DEG).
//!
//! A file without `roll`, `pitch` and `yaw` measures positions only: a laser tracker's (or
//! any device fixed in the world, `camera = world`) of a point (a reflector) on each target
//! branch, its `x, y, z` in the device's frame; the targets' placements are then points.

use crate::calibration::CalibrationError;
pub use crate::calibration::kinds::camera::{Frame, Role};
use crate::calibration::kinds::{
    CameraSite, DEFAULT_CAMERA_SIGMA_DEG, DEFAULT_CAMERA_SIGMA_MM, KindData, Observation,
};
use crate::limits::MAX_LENGTH_MM;
use crate::model::RobotTree;
use crate::table::{DataError, Row, Table, Units};
use nalgebra::{UnitQuaternion, Vector6};

/// One camera view: the target's pose in the camera's frame at one pose of the tree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// The pose (an index into [`TreeData::joints`]).
    pub pose: usize,
    /// The camera's frame (an index into [`TreeData::frames`]).
    pub camera: usize,
    /// The target's frame.
    pub target: usize,
    /// The target's pose in the camera frame: position (mm), rotation vector (rad).
    pub view: Vector6<f64>,
    /// Standard deviations of the position (mm) and of each rotation component (rad).
    pub sigma: [f64; 2],
}

/// A set of camera views of a tree, with the file line of each.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TreeData {
    /// The joint values of each pose (rad, mm), one per tree joint.
    pub joints: Vec<Vec<f64>>,
    /// The cameras and targets the views name, each once.
    pub frames: Vec<Frame>,
    /// The views.
    pub views: Vec<View>,
    /// The file line of each view.
    pub lines: Vec<usize>,
    /// Whether the views are positions only (the target's `x, y, z` in the camera's frame, a
    /// tracker's), their rotations unmeasured.
    pub position_only: bool,
    /// Whether every view's sigmas are the defaults (the file has neither a `sigma` nor a
    /// `sigma_angle` column): the noise assumed, not known.
    pub assumed_sigmas: bool,
    /// The measuring sessions (one per file), each its name and its first pose, as
    /// [`KindData::sessions`]: a camera's or target's placement made per session
    /// ([`KindOptions::per_session`](super::KindOptions::per_session)) takes one value per
    /// session. Empty: one session.
    pub sessions: Vec<(String, usize)>,
}

impl TreeData {
    /// Read a file of views of `tree` (see `docs/formats.md`); `units` from the caller take the
    /// place of the file's `# units:` line.
    pub fn from_csv_str(text: &str, tree: &RobotTree, units: Option<Units>) -> Result<Self, DataError> {
        let table = Table::parse(text)?;
        let units = table.units(units, " or give --joint-unit and --length-unit")?;
        let joints = table.columns_of(&tree.joints)?;
        let needed = |name: &str| {
            table.column(name).ok_or_else(|| {
                DataError::new(
                    table.header_line,
                    Some(name),
                    "missing column; a view has camera, target, the tree's joints, x, y, z and, unless it \
                     is a position only, roll, pitch, yaw",
                )
            })
        };
        let (camera, target) = (needed("camera")?, needed("target")?);
        let angles = ["roll", "pitch", "yaw"];
        let position_only = angles.iter().all(|a| table.column(a).is_none());
        let measured =
            if position_only { &["x", "y", "z"][..] } else { &["x", "y", "z", "roll", "pitch", "yaw"][..] };
        let axes: Vec<usize> = measured.iter().map(|a| needed(a)).collect::<Result<_, _>>()?;
        let (sigma, sigma_angle) = (table.column("sigma"), table.column("sigma_angle"));
        let assumed_sigmas = sigma.is_none() && sigma_angle.is_none();
        let mut data = Self { position_only, assumed_sigmas, ..Self::default() };
        for row in table.nonempty_rows()? {
            let camera = data.frame(tree, &table, row, camera, Role::Camera)?;
            let target = data.frame(tree, &table, row, target, Role::Target)?;
            let (a, b) = (data.frames[camera].on, data.frames[target].on);
            if a == b {
                let on = a.map_or("world", |b| tree.branches[b].tip.as_str());
                let message = format!("camera and target both on `{on}`: the view sees no joint");
                return Err(DataError::new(row.line, Some("target"), message));
            }
            if position_only && a.is_some() {
                let message = "positions only (no roll, pitch, yaw columns) are a device's fixed in the world: \
                               expected world, or give the views' roll, pitch, yaw";
                return Err(DataError::new(row.line, Some("camera"), message));
            }
            let mut v = [0.0; 6];
            for (axis, &c) in axes.iter().enumerate() {
                let value = table.number(row, c)?;
                v[axis] = match axis < 3 {
                    true => table.within(row, c, value * units.length_scale(), MAX_LENGTH_MM, "mm")?,
                    false => units.angle(value),
                };
            }
            let rotation = UnitQuaternion::from_euler_angles(v[3], v[4], v[5]).scaled_axis();
            let positive = |c: Option<usize>, scale: f64| -> Result<Option<f64>, DataError> {
                let Some(c) = c.filter(|&c| !row.cells[c].is_empty()) else { return Ok(None) };
                let value = table.number(row, c)? * scale;
                if value <= 0.0 {
                    let message = format!("{value}: expected a value > 0");
                    return Err(DataError::new(row.line, Some(&table.header[c]), message));
                }
                Ok(Some(value))
            };
            let sigma = [
                positive(sigma, units.length_scale())?.unwrap_or(DEFAULT_CAMERA_SIGMA_MM),
                positive(sigma_angle, 1.0)?.map_or(DEFAULT_CAMERA_SIGMA_DEG.to_radians(), |v| units.angle(v)),
            ];
            // Rows of one pose in a row (a camera seeing two targets) are one pose.
            let q = table.values_of(row, &joints, &tree.joints, units)?;
            if data.joints.last() != Some(&q) {
                data.joints.push(q);
            }
            data.views.push(View {
                pose: data.joints.len() - 1,
                camera,
                target,
                view: Vector6::new(v[0], v[1], v[2], rotation.x, rotation.y, rotation.z),
                sigma,
            });
            data.lines.push(row.line);
        }
        Ok(data)
    }

    /// The frame of `role` that `column` of `row` names (a branch's tip or `world`), added if new.
    fn frame(
        &mut self,
        tree: &RobotTree,
        table: &Table,
        row: &Row,
        column: usize,
        role: Role,
    ) -> Result<usize, DataError> {
        let name = &row.cells[column];
        let on = match name {
            "world" => None,
            tip => Some(tree.branch(tip).ok_or_else(|| {
                let tips: Vec<&str> = tree.branches.iter().map(|b| b.tip.as_str()).collect();
                let message = format!("`{tip}`: expected world or a tip link: {}", tips.join(", "));
                DataError::new(row.line, Some(&table.header[column]), message)
            })?),
        };
        let frame = Frame { role, on };
        Ok(match self.frames.iter().position(|f| *f == frame) {
            Some(i) => i,
            None => {
                self.frames.push(frame);
                self.frames.len() - 1
            }
        })
    }

    /// Refuse views that do not fit (for data built by hand rather than read): a pose or a
    /// frame that does not exist, joint values not one finite value per tree joint, a view not
    /// finite, a sigma not finite and above 0, a view whose camera and target are on one
    /// branch, a line missing; `dof` the tree's joints, `branches` its branches.
    pub fn check(&self, dof: usize, branches: usize) -> Result<(), CalibrationError> {
        let bad = |what: String| Err(CalibrationError::Observations(what));
        if self.lines.len() != self.views.len() {
            return bad(format!("{} lines for {} views", self.lines.len(), self.views.len()));
        }
        if let Some(k) = self.joints.iter().position(|q| q.len() != dof || q.iter().any(|v| !v.is_finite())) {
            return bad(format!("pose {k}: expected {dof} finite joint values"));
        }
        crate::calibration::kinds::check_sessions(&self.sessions)?;
        if let Some(f) = self.frames.iter().position(|f| f.on.is_some_and(|b| b >= branches)) {
            return bad(format!("frame {f}: on a branch the tree does not have"));
        }
        for (view, line) in self.views.iter().zip(&self.lines) {
            let frames = self.frames.len();
            if view.pose >= self.joints.len() || view.camera >= frames || view.target >= frames {
                return bad(format!("line {line}: a pose or frame that does not exist"));
            }
            if self.frames[view.camera].on == self.frames[view.target].on {
                return bad(format!("line {line}: camera and target on one branch: the view sees no joint"));
            }
            if self.position_only && self.frames[view.camera].on.is_some() {
                return bad(format!("line {line}: positions only are a device's fixed in the world"));
            }
            if view.view.iter().any(|v| !v.is_finite()) {
                return bad(format!("line {line}: a view of finite values expected"));
            }
            if view.sigma.iter().any(|s| !s.is_finite() || *s <= 0.0) {
                return bad(format!("line {line}: sigmas finite and above 0 expected"));
            }
        }
        Ok(())
    }

    /// The views as observations of the one problem ([`KindProblem::of_branches`]): each
    /// view's rows ([`TreeData::rows`]), camera observations at [`CameraSite::Tree`] of its
    /// camera's and target's numbers among `frames` (each of the data's frames is one of
    /// them), in order, each with the view's line.
    ///
    /// # Panics
    /// If a frame of the data is not among `frames`, or there are 65536 or more.
    ///
    /// [`KindProblem::of_branches`]: crate::calibration::kinds::KindProblem::of_branches
    pub fn observations(&self, frames: &[Frame]) -> KindData {
        let rows = self.rows();
        let number = |f: usize| {
            let at = frames.iter().position(|g| *g == self.frames[f]).expect("a frame among those given");
            u16::try_from(at).expect("fewer than 65536 frames")
        };
        let observations: Vec<Observation> = (self.views.iter())
            .flat_map(|v| {
                let site = CameraSite::Tree { camera: number(v.camera), target: number(v.target) };
                let (pose, view) = (v.pose, v.view);
                (0..rows).map(move |axis| Observation::Camera {
                    axis,
                    pose,
                    view,
                    site,
                    sigma: v.sigma[axis / 3],
                })
            })
            .collect();
        let lines = self.lines.iter().flat_map(|&l| std::iter::repeat_n(l, rows)).collect();
        let assumed_sigmas = if self.assumed_sigmas { observations.len() } else { 0 };
        let sessions = self.sessions.clone();
        KindData {
            joints: self.joints.clone(),
            observations,
            lines,
            assumed_sigmas,
            sessions,
            ..KindData::default()
        }
    }

    /// The same views as one session named `name` (a file's stem).
    pub fn named(self, name: &str) -> Self {
        Self { sessions: vec![(name.to_string(), 0)], ..self }
    }

    /// The rows of a view: 6 (position, rotation), or 3 for positions only.
    pub fn rows(&self) -> usize {
        if self.position_only { 3 } else { 6 }
    }

    /// The same views, positions only: their rotations dropped (a tracker's).
    pub fn positions_only(mut self) -> Self {
        for view in &mut self.views {
            view.view.fixed_rows_mut::<3>(3).fill(0.0);
        }
        Self { position_only: true, ..self }
    }

    /// The views taken at the poses `keep` accepts, with their lines; the poses, frames and
    /// everything else as they are (a fold of a cross-validation).
    pub fn keeping(&self, keep: impl Fn(usize) -> bool) -> Self {
        let (views, lines) =
            self.views.iter().zip(&self.lines).filter(|(v, _)| keep(v.pose)).map(|(v, l)| (*v, *l)).unzip();
        Self { views, lines, ..self.clone() }
    }

    /// These views and `other`'s in one set (the same camera or target is the same frame); an
    /// error if one set has rotations and the other positions only.
    pub fn join(mut self, other: &Self) -> Result<Self, CalibrationError> {
        if !self.views.is_empty() && !other.views.is_empty() && self.position_only != other.position_only {
            return Err(CalibrationError::Observations(
                "views with rotations and positions only cannot be fitted together".into(),
            ));
        }
        // The noise is assumed only where every file's is.
        self.assumed_sigmas = match self.views.is_empty() {
            true => other.assumed_sigmas,
            false => self.assumed_sigmas && other.assumed_sigmas,
        };
        if self.views.is_empty() {
            self.position_only = other.position_only;
        }
        let offset = self.joints.len();
        crate::calibration::kinds::join_sessions(
            &mut self.sessions,
            offset,
            (&other.sessions, other.joints.len()),
        );
        self.joints.extend(other.joints.iter().cloned());
        self.lines.extend(&other.lines);
        let mut index = Vec::with_capacity(other.frames.len());
        for frame in &other.frames {
            index.push(match self.frames.iter().position(|f| f == frame) {
                Some(i) => i,
                None => {
                    self.frames.push(*frame);
                    self.frames.len() - 1
                }
            });
        }
        self.views.extend(other.views.iter().map(|v| View {
            pose: v.pose + offset,
            camera: index[v.camera],
            target: index[v.target],
            ..*v
        }));
        Ok(self)
    }
}
