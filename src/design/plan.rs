//! The planner: candidate pools within the joint limits and constraints, and the exchange
//! algorithm of [`Design::plan`].

use super::{Criterion, Design, DesignError, Indices};
use crate::estimation::EstimationError;
use nalgebra::{DMatrix, SMatrix, SymmetricEigen, Vector3};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;

/// Configurations drawn at most per candidate asked for, before constraints give up.
pub(crate) const DRAWS_PER_CANDIDATE: usize = 100;
/// Exchange passes at most.
pub(crate) const MAX_PASSES: usize = 50;
/// Candidates tried per pose for the criteria O2-O5.
pub(crate) const SHORTLIST: usize = 32;
/// Relative improvement an exchange must bring.
const IMPROVEMENT: f64 = 1e-9;

/// How far a plan has got, for a progress bar: the candidates' rows, then the exchange's
/// passes (their number is not known in advance: passes repeat until one changes nothing, at
/// most [`Plan::MAX_PASSES`] per criterion).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanProgress {
    /// The whitened rows of `done` candidates computed, of `of`.
    Rows {
        /// Candidates done.
        done: usize,
        /// Candidates in all.
        of: usize,
    },
    /// Pass `pass` (from 1) of the exchange: `done` of the set's `of` poses tried.
    Pass {
        /// The pass, from 1.
        pass: usize,
        /// Poses of the set tried in this pass.
        done: usize,
        /// Poses in the set.
        of: usize,
    },
}

/// A joint range the poses must avoid: `range` in rad (mm for a prismatic joint), inclusive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcludedRange {
    /// The joint (0-based).
    pub joint: usize,
    /// Lowest and highest excluded value.
    pub range: [f64; 2],
}

/// Where candidate poses may be: always within the joint limits, and within these.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Constraints {
    /// The tool point (nominal kinematics, mm, measuring frame) must lie in this box: lowest
    /// and highest corner.
    pub tool_box: Option<[Vector3<f64>; 2]>,
    /// Joint ranges to avoid.
    pub excluded: Vec<ExcludedRange>,
}

impl Constraints {
    /// Whether joint values `q` with the tool point at `tool` satisfy the constraints.
    pub fn admits(&self, q: &[f64], tool: &Vector3<f64>) -> bool {
        let in_box =
            self.tool_box.is_none_or(|[low, high]| (0..3).all(|i| tool[i] >= low[i] && tool[i] <= high[i]));
        in_box && self.excluded.iter().all(|e| q[e.joint] < e.range[0] || q[e.joint] > e.range[1])
    }

    /// The constraints in words (mm and degrees), for messages.
    pub fn describe(&self, model: &crate::model::RobotModel) -> String {
        let mut parts = vec!["joint limits".to_string()];
        if let Some([low, high]) = &self.tool_box {
            parts.push(format!(
                "tool in the box x {}..{}, y {}..{}, z {}..{} mm",
                low.x, high.x, low.y, high.y, low.z, high.z
            ));
        }
        for e in &self.excluded {
            let joint = &model.joints[e.joint];
            let unit = |v: f64| match joint.kind {
                crate::model::JointKind::Revolute => format!("{} deg", crate::model::degrees(v)),
                crate::model::JointKind::Prismatic => format!("{v} mm"),
            };
            parts.push(format!("{} not in {}..{}", joint.name, unit(e.range[0]), unit(e.range[1])));
        }
        parts.join(", ")
    }

    fn validate(&self, model: &crate::model::RobotModel) -> Result<(), DesignError> {
        let bad = |s: String| Err(DesignError::Constraint(s));
        if let Some([low, high]) = &self.tool_box
            && (0..3).any(|i| !low[i].is_finite() || !high[i].is_finite() || low[i] > high[i])
        {
            return bad(format!("tool box from {low:?} to {high:?}: expected finite corners, lowest first"));
        }
        for e in &self.excluded {
            if e.joint >= model.dof() {
                return bad(format!(
                    "excluded range of joint {} of a {}-joint robot",
                    e.joint + 1,
                    model.dof()
                ));
            }
            if !(e.range[0].is_finite() && e.range[1].is_finite() && e.range[0] <= e.range[1]) {
                let name = &model.joints[e.joint].name;
                return bad(format!("excluded range of {name}: expected finite values, lowest first"));
            }
        }
        Ok(())
    }
}

/// A pool of candidate poses.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidates {
    /// Joint values of each candidate (rad, mm).
    pub joints: Vec<Vec<f64>>,
    /// Configurations drawn to find them.
    pub draws: usize,
}

/// A planned pose set.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The chosen poses (rad, mm), in the pool's order.
    pub joints: Vec<Vec<f64>>,
    /// Their indices in the pool, ascending.
    pub chosen: Vec<usize>,
    /// What was maximised.
    pub criterion: Criterion,
    /// Its value on the starting set (the first poses of the pool).
    pub initial: f64,
    /// Its value on the chosen set.
    pub value: f64,
    /// Exchange passes made.
    pub passes: usize,
    /// Exchanges made.
    pub exchanges: usize,
    /// Candidates that could be used (a positive definite `V_k`).
    pub usable: usize,
}

impl Plan {
    /// Exchange passes at most, per criterion (D first; then O2-O5 by their own value).
    pub const MAX_PASSES: usize = MAX_PASSES;
}

impl Design {
    /// Up to `count` candidate poses uniform within the joint limits that satisfy
    /// `constraints`, drawing at most `count * DRAWS_PER_CANDIDATE` configurations. Without
    /// constraints they are [`crate::model::RobotModel::uniform_configurations`] from the same generator.
    pub fn candidates(
        &self,
        count: usize,
        constraints: &Constraints,
        rng: &mut ChaCha8Rng,
    ) -> Result<Candidates, DesignError> {
        constraints.validate(&self.model)?;
        let mut joints = Vec::with_capacity(count);
        let (mut draws, limit) = (0, count.saturating_mul(DRAWS_PER_CANDIDATE));
        while joints.len() < count && draws < limit {
            let q = self.model.uniform_configurations(1, rng).pop().expect("one configuration");
            draws += 1;
            let tool = match constraints.tool_box {
                Some(_) => self.nominal.position(&q),
                None => Vector3::zeros(),
            };
            if constraints.admits(&q, &tool) {
                joints.push(q);
            }
        }
        if joints.is_empty() {
            return Err(DesignError::EmptyPool { draws, constraints: constraints.describe(&self.model) });
        }
        Ok(Candidates { joints, draws })
    }

    /// The memory [`Design::plan_seeded`] will need at most for a pool of `candidates`, in
    /// bytes: per candidate its joint values and the whitened `b x r` rows, held twice, plus
    /// the exchange's gradient rows (`8 dof + 32 + 3 x 8 b r`; `b` 3 or 6, `r` the identified
    /// parameters). A bound to refuse absurd requests before allocating.
    pub fn plan_memory_estimate(&self, candidates: usize) -> u64 {
        let (b, r, dof) = (self.measured.rows() as u64, self.columns.len() as u64, self.model().dof() as u64);
        (candidates as u64).saturating_mul(8 * dof + 32 + 24 * b * r)
    }

    /// The work of one pass of [`Design::plan_seeded`]'s exchange over `candidates` for
    /// `points` poses, in products of rows and parameters (`candidates x points x b x r`),
    /// bounded by [`crate::limits::MAX_WORK`].
    pub fn plan_work(&self, candidates: usize, points: usize) -> u64 {
        let (b, r) = (self.measured.rows() as u64, self.columns.len() as u64);
        (candidates as u64).saturating_mul(points as u64).saturating_mul(b * r)
    }

    /// Plan `points` poses from a pool of `candidates` drawn with ChaCha8 seeded by `seed`
    /// (stream 0): the same arguments give the same poses.
    pub fn plan_seeded(
        &self,
        points: usize,
        candidates: usize,
        constraints: &Constraints,
        criterion: Criterion,
        seed: u64,
    ) -> Result<(Plan, Candidates), DesignError> {
        self.plan_seeded_reporting(points, candidates, constraints, criterion, seed, &|_| {})
    }

    /// [`Design::plan_seeded`], telling `progress` how far it has got (after every 1024
    /// candidates' rows and every pose of each exchange pass).
    pub fn plan_seeded_reporting(
        &self,
        points: usize,
        candidates: usize,
        constraints: &Constraints,
        criterion: Criterion,
        seed: u64,
        progress: &dyn Fn(PlanProgress),
    ) -> Result<(Plan, Candidates), DesignError> {
        self.check_points(points)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pool = self.candidates(candidates, constraints, &mut rng)?;
        let plan = self.plan_reporting(&pool.joints, points, criterion, progress)?;
        Ok((plan, pool))
    }

    fn check_points(&self, points: usize) -> Result<(), DesignError> {
        let (rows, identifiable) = (self.measured.rows(), self.columns.len());
        if points == 0 || points * rows < identifiable {
            return Err(DesignError::TooFewPoses {
                points,
                equations: points * rows,
                identifiable,
                minimum: self.minimum_poses(),
            });
        }
        Ok(())
    }

    /// Choose `points` poses from `pool` that maximise `criterion`. Candidates whose `V_k` has
    /// no Cholesky factor are skipped.
    ///
    /// The planner: `N` poses chosen from a pool of candidates, within the joint limits and the
    /// user's constraints, to maximise a [`Criterion`] of the whitened (or, without a noise
    /// model, the column-scaled) identification Jacobian.
    ///
    /// **D-optimality (and O1) by Fedorov's exchange**, in the modified form of Cook and
    /// Nachtsheim (1980): the information matrix of the set is `M = sum_k A_k^T A_k`, with `A_k`
    /// the whitened `b x r` rows of pose `k` (`b` = 3 or 6), precomputed once for every candidate.
    /// In turn, each pose `i` of the set is exchanged for the candidate `j` outside it that
    /// multiplies `det M` most, if any does; passes repeat until one changes nothing. The ratio
    /// comes from the matrix determinant lemma for the rank-`2b` update
    /// `M' = M + A_j^T A_j - A_i^T A_i`:
    ///
    /// `det M' / det M = det(I + G_jj) det(I - G_ii + G_ij (I + G_jj)^-1 G_ji)`,
    /// `G_uv = A_u M^-1 A_v^T` (`b x b`),
    ///
    /// so a trial costs a few `b x b` products: `A M^-1` (one product of the tall candidate matrix
    /// by `M^-1`) is recomputed after each exchange, `G_ji` for all `j` is one product per `i`.
    /// `M` gets a ridge of `1e-10 trace(M) / r` so that a singular starting set can be improved.
    ///
    /// **O2-O5** have no such update. After the D-optimal exchange, each pose of the set is tried
    /// against the 32 candidates with the largest D-ratio for it, the criterion of each
    /// trial set computed from the eigenvalues of its `M'` (`sigma_i = sqrt(lambda_i)`), and
    /// exchanged for the best if it improves the criterion; passes repeat as above.
    ///
    /// The starting set is the first `N` usable candidates of the pool (for a seeded pool, a
    /// uniform random set); ties go to the lowest candidate. Everything is sequential and
    /// deterministic: the same pool gives the same poses on any number of threads.
    pub fn plan(&self, pool: &[Vec<f64>], points: usize, criterion: Criterion) -> Result<Plan, DesignError> {
        self.plan_reporting(pool, points, criterion, &|_| {})
    }

    /// [`Design::plan`], telling `progress` how far it has got (after every 1024 candidates'
    /// rows and every pose of each exchange pass).
    pub fn plan_reporting(
        &self,
        pool: &[Vec<f64>],
        points: usize,
        criterion: Criterion,
        progress: &dyn Fn(PlanProgress),
    ) -> Result<Plan, DesignError> {
        self.check_points(points)?;
        self.check(pool)?;
        let (rows, r) = (self.measured.rows(), self.columns.len());
        let whitened = self.weighted();
        let mut usable = Vec::with_capacity(pool.len());
        let mut a = DMatrix::zeros(rows * pool.len(), r);
        for (k, q) in pool.iter().enumerate() {
            if k % 1024 == 0 {
                progress(PlanProgress::Rows { done: k, of: pool.len() });
            }
            match self.pose_rows(q, whitened) {
                Ok(block) => {
                    a.rows_mut(rows * usable.len(), rows).copy_from(&block);
                    usable.push(k);
                }
                Err(EstimationError::NotPositiveDefinite { .. }) => continue,
                Err(e) => return Err(e.into()),
            }
        }
        if usable.len() < points {
            return Err(DesignError::PoolTooSmall { usable: usable.len(), points });
        }
        let a = a.rows(0, rows * usable.len()).into_owned();
        let pick =
            |set: &[usize]| -> Vec<Vec<f64>> { set.iter().map(|&j| pool[usable[j]].clone()).collect() };
        let initial = self.criterion(&pick(&(0..points).collect::<Vec<_>>()), criterion)?;
        let mut exchange = Exchange::new(a, rows, points);
        match rows {
            3 => exchange.run::<3>(criterion, progress),
            6 => exchange.run::<6>(criterion, progress),
            b => unreachable!("{b} rows per pose: position (3) or pose (6)"),
        }
        let mut set = exchange.set.clone();
        set.sort_unstable();
        let joints = pick(&set);
        let value = self.criterion(&joints, criterion)?;
        Ok(Plan {
            joints,
            chosen: set.iter().map(|&j| usable[j]).collect(),
            criterion,
            initial,
            value,
            passes: exchange.passes,
            exchanges: exchange.exchanges,
            usable: usable.len(),
        })
    }
}

/// The state of an exchange: the candidates' rows, the set, and `M^-1` with what derives
/// from it.
struct Exchange {
    /// Candidate rows, `b * n x r`: candidate `j` in rows `b j .. b j + b`.
    a: DMatrix<f64>,
    b: usize,
    set: Vec<usize>,
    in_set: Vec<bool>,
    /// `A M^-1`.
    w: DMatrix<f64>,
    /// The diagonal blocks `G_jj = A_j M^-1 A_j^T`, stacked (`b * n x b`).
    g: DMatrix<f64>,
    passes: usize,
    exchanges: usize,
}

impl Exchange {
    fn new(a: DMatrix<f64>, b: usize, points: usize) -> Self {
        let n = a.nrows() / b;
        let mut in_set = vec![false; n];
        in_set[..points].iter_mut().for_each(|s| *s = true);
        let mut exchange = Self {
            w: DMatrix::zeros(0, 0),
            g: DMatrix::zeros(0, 0),
            a,
            b,
            set: (0..points).collect(),
            in_set,
            passes: 0,
            exchanges: 0,
        };
        exchange.refresh();
        exchange
    }

    /// `M = sum A_k^T A_k` over the set.
    fn information(&self, set: &[usize]) -> DMatrix<f64> {
        let r = self.a.ncols();
        let mut m = DMatrix::zeros(r, r);
        for &k in set {
            let block = self.a.rows(k * self.b, self.b);
            m += block.tr_mul(&block);
        }
        m
    }

    /// `M^-1` (with its ridge), `A M^-1` and the blocks `G_jj` for the current set.
    fn refresh(&mut self) {
        let mut m = self.information(&self.set);
        let r = m.nrows();
        let ridge = (1e-10 * m.trace() / r as f64).max(f64::MIN_POSITIVE);
        for d in 0..r {
            m[(d, d)] += ridge;
        }
        let m_inv = match m.clone().cholesky() {
            Some(c) => c.inverse(),
            None => m.pseudo_inverse(0.0).unwrap_or_else(|_| DMatrix::zeros(r, r)),
        };
        self.w = crate::linalg::mul(&self.a, &m_inv);
        let (b, rows) = (self.b, self.a.nrows());
        let mut g = vec![0.0; rows * b];
        let (w, a) = (self.w.as_slice(), self.a.as_slice());
        for c in 0..r {
            let (wc, ac) = (&w[c * rows..(c + 1) * rows], &a[c * rows..(c + 1) * rows]);
            for r2 in 0..b {
                let gc = &mut g[r2 * rows..(r2 + 1) * rows];
                for j in 0..rows / b {
                    let base = j * b;
                    let x = ac[base + r2];
                    for r1 in 0..b {
                        gc[base + r1] += wc[base + r1] * x;
                    }
                }
            }
        }
        self.g = DMatrix::from_vec(rows, b, g);
    }

    /// `det M' / det M` for exchanging set member `i` for each candidate (minus infinity for
    /// those in the set).
    fn ratios<const B: usize>(&self, i: usize, out: &mut Vec<f64>) {
        let n = self.a.nrows() / B;
        let a_i_t = self.a.rows(i * B, B).transpose();
        let y = crate::linalg::mul(&self.w, &a_i_t);
        let block = |m: &DMatrix<f64>, j: usize| SMatrix::<f64, B, B>::from_fn(|r, c| m[(j * B + r, c)]);
        let i_minus_gii = SMatrix::<f64, B, B>::identity() - block(&self.g, i);
        out.clear();
        out.extend((0..n).map(|j| {
            if self.in_set[j] {
                return f64::NEG_INFINITY;
            }
            let p = SMatrix::<f64, B, B>::identity() + block(&self.g, j);
            let g_ji = block(&y, j);
            // Both factors are symmetric, and positive definite while M' is (it has the ridge).
            let Some(p) = p.cholesky() else { return f64::NEG_INFINITY };
            let schur = i_minus_gii + g_ji.transpose() * p.solve(&g_ji);
            match schur.cholesky() {
                Some(s) => (p.l_dirty().diagonal().product() * s.l_dirty().diagonal().product()).powi(2),
                None => 0.0,
            }
        }));
    }

    fn swap(&mut self, position: usize, j: usize) {
        self.in_set[self.set[position]] = false;
        self.in_set[j] = true;
        self.set[position] = j;
        self.exchanges += 1;
        self.refresh();
    }

    fn run<const B: usize>(&mut self, criterion: Criterion, progress: &dyn Fn(PlanProgress)) {
        let of = self.set.len();
        let mut ratios = Vec::new();
        // D-optimal exchange.
        for _ in 0..MAX_PASSES {
            self.passes += 1;
            let mut changed = false;
            for position in 0..self.set.len() {
                progress(PlanProgress::Pass { pass: self.passes, done: position, of });
                self.ratios::<B>(self.set[position], &mut ratios);
                let mut best = (1.0 + IMPROVEMENT, None);
                for (j, &ratio) in ratios.iter().enumerate() {
                    if ratio > best.0 {
                        best = (ratio, Some(j));
                    }
                }
                if let Some(j) = best.1 {
                    self.swap(position, j);
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        if matches!(criterion, Criterion::D | Criterion::O1) {
            return;
        }
        // The other criteria: the D shortlist of each pose, judged by the criterion itself.
        let points = self.set.len();
        let mut current = self.value(&self.information(&self.set), criterion, points);
        for _ in 0..MAX_PASSES {
            self.passes += 1;
            let mut changed = false;
            for position in 0..self.set.len() {
                progress(PlanProgress::Pass { pass: self.passes, done: position, of });
                let i = self.set[position];
                self.ratios::<B>(i, &mut ratios);
                let mut order: Vec<usize> = (0..ratios.len()).filter(|&j| !self.in_set[j]).collect();
                order.sort_by(|&x, &y| ratios[y].total_cmp(&ratios[x]).then(x.cmp(&y)));
                let a_i = self.a.rows(i * B, B);
                let base = self.information(&self.set) - a_i.tr_mul(&a_i);
                let mut best = (current + IMPROVEMENT * current.abs(), None);
                for &j in order.iter().take(SHORTLIST) {
                    let a_j = self.a.rows(j * B, B);
                    let value = self.value(&(&base + a_j.tr_mul(&a_j)), criterion, points);
                    if value > best.0 {
                        best = (value, Some(j));
                    }
                }
                if let (value, Some(j)) = best {
                    current = value;
                    self.swap(position, j);
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
    }

    /// The criterion of the set whose information matrix is `m`.
    fn value(&self, m: &DMatrix<f64>, criterion: Criterion, points: usize) -> f64 {
        let mut s: Vec<f64> =
            SymmetricEigen::new(m.clone()).eigenvalues.iter().map(|&l| l.max(0.0).sqrt()).collect();
        s.sort_by(|x, y| y.total_cmp(x));
        Indices::from_singular_values(&s, points, m.nrows()).criterion(criterion)
    }
}
