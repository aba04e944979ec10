//! The blocks `V_k` of a [`KindProblem`], built block by block: each pose's observations read
//! the frames and manipulator Jacobians of the points they see (computed for that block
//! alone, in scratch reused block after block), their joint-noise rows `g_kj^T J_kj` and the
//! entries of `V_k` from them. Nothing is held for every observation but the result, and the
//! blocks are filled in parallel, each entry by the same arithmetic on any number of threads.

use super::{BlockFrames, BlockJacobians, KindProblem, ViewMemo};
use crate::kinematics::{ChainAt, Measured, points_manipulator};
use nalgebra::{DMatrix, Isometry3, Matrix6xX, Vector3};
use rayon::prelude::*;
use std::ops::Range;

/// Blocks (poses) per part of the parallel fills: each part's rows are one piece of `V`.
const BLOCKS_PER_PART: usize = 256;

/// One block's joint-noise rows, its buffers reused block after block: for each of the
/// block's observations (`starts[a]..starts[a + 1]`), one row `g_kj^T J_kj` (`dof` numbers)
/// per pose `j` it sees (`poses`), and the same times `Sigma_q` (`weighted`).
struct JointRows {
    frames: BlockJacobians,
    /// A camera view's rows, computed once for its six.
    memo: ViewMemo,
    /// The manipulator Jacobian of one point at one pose.
    jacobian: Matrix6xX<f64>,
    starts: Vec<usize>,
    poses: Vec<usize>,
    rows: Vec<f64>,
    weighted: Vec<f64>,
}

impl JointRows {
    /// Empty rows for a robot of `dof` joints.
    fn new(dof: usize) -> Self {
        let (starts, poses, rows, weighted) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        Self {
            frames: BlockJacobians::default(),
            memo: ViewMemo::default(),
            jacobian: Matrix6xX::zeros(dof),
            starts,
            poses,
            rows,
            weighted,
        }
    }

    /// The rows of the observations `range` of `problem`, its points at `at`, the set-up at
    /// `views` ([`KindProblem::session_views`]); weighted by `sigma_q` if given. Each row is
    /// `g^T J` summed over `J`'s rows in order, and its weighted one `(g^T J) Sigma_q` over
    /// `Sigma_q`'s rows in order, as nalgebra's products of a row by a matrix sum them.
    fn fill(
        &mut self,
        problem: &KindProblem<'_>,
        (at, views): (&[ChainAt], &[Vec<f64>]),
        range: Range<usize>,
        sigma_q: Option<&DMatrix<f64>>,
    ) {
        self.frames.fill_manipulator(problem, at, range.clone(), &mut self.jacobian);
        let (poses, rows, dof) =
            (problem.data.joints.len(), problem.measured().rows(), self.jacobian.ncols());
        self.starts.clear();
        self.poses.clear();
        self.rows.clear();
        self.weighted.clear();
        for o in &problem.data.observations[range] {
            self.starts.push(self.poses.len());
            let f = problem.predict(o, &BlockFrames { block: &self.frames }, views, &mut self.memo);
            for &(n, g) in &f.by_point[..f.poses] {
                let jacobian = self.frames.get(n, rows * dof);
                let at = self.rows.len();
                for column in jacobian.chunks_exact(rows) {
                    let mut sum = g[0] * column[0];
                    for r in 1..rows {
                        sum += g[r] * column[r];
                    }
                    self.rows.push(sum);
                }
                self.poses.push(n % poses);
                let Some(sigma_q) = sigma_q else { continue };
                for c in 0..dof {
                    let mut sum = self.rows[at] * sigma_q[(0, c)];
                    for k in 1..dof {
                        sum += self.rows[at + k] * sigma_q[(k, c)];
                    }
                    self.weighted.push(sum);
                }
            }
        }
        self.starts.push(self.poses.len());
    }

    /// The joint noise's part of the entry `(a, b)` of the block (observations `a` and `b` of
    /// it): `sum_j (g_aj^T J_aj Sigma_q) . (g_bj^T J_bj)` over the poses `j` both see.
    fn entry(&self, a: usize, b: usize) -> f64 {
        let dof = self.jacobian.ncols();
        let dot = move |e: usize, e2: usize| {
            let (x, y) = (&self.weighted[e * dof..(e + 1) * dof], &self.rows[e2 * dof..(e2 + 1) * dof]);
            x.iter().zip(y).fold(0.0, |s, (x, y)| s + x * y)
        };
        let common = (self.starts[a]..self.starts[a + 1]).flat_map(|e| {
            (self.starts[b]..self.starts[b + 1])
                .filter(move |&e2| self.poses[e2] == self.poses[e])
                .map(move |e2| dot(e, e2))
        });
        common.sum()
    }
}

impl BlockJacobians {
    /// The frames and the manipulator Jacobians (their first `rows` rows, `rows x dof`
    /// column-major, in place of `H_j`) of the points at the poses that the observations
    /// `range` of `problem` read, at `at`; `jacobian` is scratch.
    fn fill_manipulator(
        &mut self,
        problem: &KindProblem<'_>,
        at: &[ChainAt],
        range: Range<usize>,
        jacobian: &mut Matrix6xX<f64>,
    ) {
        self.keys.clear();
        for o in &problem.data.observations[range] {
            self.keys.extend(problem.seen(o));
        }
        self.keys.sort_unstable();
        self.keys.dedup();
        let (poses, rows) = (problem.data.joints.len(), problem.measured().rows());
        self.values.clear();
        self.frames.clear();
        if problem.measured() == Measured::Position && at.len() > 1 {
            return self.fill_manipulator_points(problem, at, jacobian.ncols());
        }
        for &n in &self.keys {
            let (at, q) = (&at[n / poses], &problem.data.joints[n % poses]);
            // Zeros: a tree's branch writes its own joints' columns only.
            jacobian.fill(0.0);
            at.manipulator_jacobian(q, jacobian);
            for column in jacobian.column_iter() {
                self.values.extend(column.iter().take(rows));
            }
            self.frames.push(at.pose(q));
        }
    }

    /// [`BlockJacobians::fill_manipulator`] of points alone (markers and the tool point, no
    /// frame): every point of a pose from one walk of the arm they share each way
    /// ([`points_manipulator`]: bit for bit each point's own `J` and pose), each needed one's
    /// first 3 rows (`3 x dof`, column-major) copied out.
    fn fill_manipulator_points(&mut self, problem: &KindProblem<'_>, at: &[ChainAt], dof: usize) {
        let (poses, points) = (problem.data.joints.len(), at.len());
        self.poses.clear();
        self.poses.extend(self.keys.iter().map(|n| n % poses));
        self.poses.sort_unstable();
        self.poses.dedup();
        self.manipulators.resize_with(points, || Matrix6xX::zeros(dof));
        self.ends.resize(points, Isometry3::identity());
        self.walked.resize(points, Vector3::zeros());
        self.values.resize(self.keys.len() * 3 * dof, 0.0);
        self.frames.resize(self.keys.len(), Isometry3::identity());
        for &pose in &self.poses {
            let q = problem.joint_trig(pose);
            points_manipulator(at, q, &mut self.manipulators, &mut self.ends, &mut self.walked);
            for (k, &n) in self.keys.iter().enumerate().filter(|(_, n)| *n % poses == pose) {
                let jacobian = self.manipulators[n / poses].as_slice();
                let out = &mut self.values[3 * dof * k..3 * dof * (k + 1)];
                for (c, into) in out.chunks_exact_mut(3).enumerate() {
                    into.copy_from_slice(&jacobian[6 * c..6 * c + 3]);
                }
                self.frames[k] = self.ends[n / poses];
            }
        }
    }
}

impl KindProblem<'_> {
    /// The blocks (poses) in parts of [`BLOCKS_PER_PART`], each with its rows.
    fn parts(&self) -> Vec<(Range<usize>, Range<usize>)> {
        let points = self.blocks.points(self.data.observations.len());
        (0..points)
            .step_by(BLOCKS_PER_PART)
            .map(|first| {
                let last = (first + BLOCKS_PER_PART).min(points);
                (first..last, self.blocks.range(first).start..self.blocks.range(last - 1).end)
            })
            .collect()
    }

    /// The chains at the problem's values and each session's set-up values.
    /// The joints' sines and cosines too, found here before the parallel walks
    /// ([`KindProblem::trig_table`]) for the points alone that walk with them.
    fn at_start(&self) -> (Vec<ChainAt>, Vec<Vec<f64>>) {
        if self.measured() == Measured::Position {
            self.trig_table();
        }
        let at = self.chains.iter().map(|c| c.with_errors(&self.fixed)).collect();
        (at, self.session_views(&self.setup_values))
    }

    /// The entries of block `k` ([`KindProblem::covariance_blocks`]), each given to `put` with
    /// its place `(a, b)` in the block, `b <= a` (only `a == b` if `diagonal`).
    fn block_entries(
        &self,
        start: (&[ChainAt], &[Vec<f64>]),
        k: usize,
        (scratch, sigma_q): (&mut JointRows, Option<&DMatrix<f64>>),
        diagonal: bool,
        mut put: impl FnMut(usize, usize, f64),
    ) {
        let r = self.blocks.range(k);
        if sigma_q.is_some() {
            scratch.fill(self, start, r.clone(), sigma_q);
        }
        for (a, i) in r.clone().enumerate() {
            for (b, i2) in r.clone().enumerate().take(a + 1).skip(if diagonal { a } else { 0 }) {
                let through_joints = if sigma_q.is_some() { scratch.entry(a, b) } else { 0.0 };
                put(a, b, through_joints + self.data.measurement_covariance(i, i2));
            }
        }
    }

    /// The blocks `V_k` of every pose's observations (consecutive observations made at one
    /// pose, [`pose_blocks`](super::pose_blocks)), stacked: entry `(i, i')` of a block is
    /// `sum_j (g_ij^T J_ij) Sigma_q (g_i'j^T J_i'j)^T + delta_ii' sigma_i^2` (plus a device's
    /// covariance between two coordinates of one point, [`KindData::measurement_covariance`]),
    /// `j` over the poses both observations see, `J_ij` the manipulator Jacobian of observation
    /// `i`'s point at pose `j`: the joint noise of a pose moves every point seen there at
    /// once. At the start values; without `joint_noise`, the measurement variances alone.
    ///
    /// [`KindData::measurement_covariance`]: super::KindData::measurement_covariance
    pub(super) fn covariance_blocks(&self, joint_noise: Option<&DMatrix<f64>>) -> DMatrix<f64> {
        let (n, width) = (self.data.observations.len(), self.blocks.width());
        let mut v = DMatrix::zeros(n, width);
        if n == 0 || width == 0 {
            return v;
        }
        let parts = self.parts();
        // Each part's rows of every column of `v`, filled in parallel.
        let mut pieces: Vec<Vec<&mut [f64]>> = parts.iter().map(|_| Vec::with_capacity(width)).collect();
        for column in v.as_mut_slice().chunks_exact_mut(n) {
            let mut rest = column;
            for (piece, (_, rows)) in pieces.iter_mut().zip(&parts) {
                let (mine, others) = std::mem::take(&mut rest).split_at_mut(rows.len());
                piece.push(mine);
                rest = others;
            }
        }
        let (at, views) = self.at_start();
        let dof = self.chains[0].dof();
        (pieces.into_par_iter().zip(parts)).for_each_init(
            || JointRows::new(dof),
            |scratch, (mut piece, (blocks, rows))| {
                for k in blocks {
                    let first = self.blocks.range(k).start - rows.start;
                    let put = |a: usize, b: usize, value: f64| {
                        piece[b][first + a] = value;
                        piece[a][first + b] = value;
                    };
                    self.block_entries((&at, &views), k, (scratch, joint_noise), false, put);
                }
            },
        );
        v
    }

    /// The diagonal of the blocks `V_k` ([`KindProblem::covariance_blocks`]): each
    /// observation's variance, without building the blocks.
    pub(crate) fn variances(&self, joint_noise: Option<&DMatrix<f64>>) -> Vec<f64> {
        let mut variances = vec![0.0; self.data.observations.len()];
        let parts = self.parts();
        let mut pieces = Vec::with_capacity(parts.len());
        let mut rest = variances.as_mut_slice();
        for (_, rows) in &parts {
            let (mine, others) = std::mem::take(&mut rest).split_at_mut(rows.len());
            pieces.push(mine);
            rest = others;
        }
        let (at, views) = self.at_start();
        let dof = self.chains[0].dof();
        (pieces.into_par_iter().zip(parts)).for_each_init(
            || JointRows::new(dof),
            |scratch, (piece, (blocks, rows))| {
                for k in blocks {
                    let first = self.blocks.range(k).start - rows.start;
                    let put = |a: usize, _: usize, value: f64| piece[first + a] = value;
                    self.block_entries((&at, &views), k, (scratch, joint_noise), true, put);
                }
            },
        );
        variances
    }

    /// Each pose block's joint-noise Jacobian for feasible GLS ([`KindProblem::noise_layout`]):
    /// its observations' rows `g_kj^T J_kj` by the distinct poses `j` they see, side by side.
    pub(super) fn noise_jacobians(&self) -> Vec<DMatrix<f64>> {
        let points = self.blocks.points(self.data.observations.len());
        let (at, views) = self.at_start();
        let dof = self.chains[0].dof();
        (0..points)
            .into_par_iter()
            .map_init(
                || (JointRows::new(dof), Vec::new()),
                |(scratch, poses), k| {
                    let range = self.blocks.range(k);
                    scratch.fill(self, (&at, &views), range.clone(), None);
                    poses.clone_from(&scratch.poses);
                    poses.sort_unstable();
                    poses.dedup();
                    let mut block = DMatrix::zeros(range.len(), poses.len() * dof);
                    for r in 0..range.len() {
                        for e in scratch.starts[r]..scratch.starts[r + 1] {
                            let p = poses.binary_search(&scratch.poses[e]).expect("a pose of the block");
                            for (c, g) in scratch.rows[e * dof..(e + 1) * dof].iter().enumerate() {
                                block[(r, p * dof + c)] += g;
                            }
                        }
                    }
                    block
                },
            )
            .collect()
    }
}
