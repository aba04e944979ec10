//! The block structure of `V = blockdiag(V_k)`: which rows of `y = H x + e` belong to point
//! `k`, and the operations on stacked blocks that never form an `N_m x N_m` matrix.
//!
//! A point is what shares one block: a pose's three coordinates, a pose's six, all markers
//! seen at one pose (`3 x markers` rows), or every observation taken at one pose of a mixed
//! data set (a ball bar's length and a camera's view of the same pose are correlated through
//! its joint noise, `V_k = G_k Sigma_q G_k^T + Sigma_m,k`). Blocks are stacked `N_m x w`, `w`
//! the largest block: point `k`'s block is its rows' first `size_k` columns.

use super::{EstimationError, Estimator, RowCovariance};
use nalgebra::allocator::Allocator;
use nalgebra::storage::{IsContiguous, RawStorage, StorageMut};
use nalgebra::{Const, DMatrix, DVector, DefaultAllocator, Dim, Dyn, Matrix, OMatrix, SMatrix};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};

/// Where each point's rows lie in the stacked system.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Blocks {
    /// Every point has this many rows: 3 (position), 6 (pose) or 3 per marker.
    Uniform(usize),
    /// Point `k` has rows `starts[k]..starts[k + 1]`; the last entry is `N_m`.
    Ragged(Vec<usize>),
}

impl Blocks {
    /// Consecutive points of these sizes (rows each).
    pub fn from_sizes(sizes: impl IntoIterator<Item = usize>) -> Self {
        let mut starts = vec![0];
        for size in sizes {
            starts.push(starts.last().copied().unwrap_or(0) + size);
        }
        Self::Ragged(starts)
    }

    /// The widest block: the columns of the stacked blocks.
    pub fn width(&self) -> usize {
        match self {
            Self::Uniform(b) => *b,
            Self::Ragged(starts) => starts.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0),
        }
    }

    /// The number of points in `rows` rows.
    pub fn points(&self, rows: usize) -> usize {
        match self {
            Self::Uniform(b) => rows.checked_div(*b).unwrap_or(0),
            Self::Ragged(starts) => starts.len().saturating_sub(1),
        }
    }

    /// The rows of point `k`.
    pub fn range(&self, k: usize) -> Range<usize> {
        match self {
            Self::Uniform(b) => k * b..(k + 1) * b,
            Self::Ragged(starts) => starts[k]..starts[k + 1],
        }
    }

    /// The rows of every point of a system of `rows` rows, in order.
    pub fn ranges(&self, rows: usize) -> impl Iterator<Item = Range<usize>> + '_ {
        (0..self.points(rows)).map(|k| self.range(k))
    }

    /// Whether these blocks cover exactly `rows` rows, every block at least one.
    pub fn covers(&self, rows: usize) -> bool {
        match self {
            Self::Uniform(b) => *b > 0 && rows % b == 0,
            Self::Ragged(starts) => starts.last() == Some(&rows) && starts.windows(2).all(|w| w[0] < w[1]),
        }
    }

    /// Block `k` of the stacked `v` (its rows, its first `size_k` columns).
    pub fn block<'v>(&self, v: &'v DMatrix<f64>, k: usize) -> nalgebra::DMatrixView<'v, f64> {
        let r = self.range(k);
        v.view((r.start, 0), (r.len(), r.len()))
    }

    /// The diagonal of the stacked blocks `v`: each row's variance.
    pub fn diagonal(&self, v: &DMatrix<f64>) -> Vec<f64> {
        self.ranges(v.nrows()).flat_map(|r| r.clone().map(move |i| v[(i, i - r.start)])).collect()
    }
}

/// Check that the stacked blocks `v` are finite and each block symmetric.
pub(crate) fn check_covariance(v: &DMatrix<f64>, blocks: &Blocks) -> Result<(), EstimationError> {
    super::finite("V", v.as_slice(), v.nrows())?;
    for k in 0..blocks.points(v.nrows()) {
        let block = blocks.block(v, k);
        let (b, tolerance) = (block.nrows(), 1e-9 * block.amax());
        if (0..b).any(|i| (0..i).any(|j| (block[(i, j)] - block[(j, i)]).abs() > tolerance)) {
            return Err(EstimationError::Dimensions(format!("V_k of point {k} is not symmetric")));
        }
    }
    Ok(())
}

/// `S_k` of every block (`L_k^-1` by Cholesky for Gauss-Markov, a diagonal for the others),
/// stacked like `v`, and the covariance of the whitened errors `S_k V_k S_k^T`: `c` alone
/// when every block is `c I` to a relative 1e-9 ([`identity_multiple`]; Gauss-Markov's, `c = 1`
/// to rounding), never written out; else the blocks stacked like `v`, from the `S_k` written.
/// Blocks of 3 and 6 rows are kept on the stack.
pub(crate) fn block_weights(
    v: &DMatrix<f64>,
    blocks: &Blocks,
    estimator: Estimator,
) -> Result<(DMatrix<f64>, RowCovariance), EstimationError> {
    let (rows, width) = v.shape();
    let mut s = DMatrix::zeros(rows, width);
    let bounds = point_parts(blocks, rows).1;
    // The first block's whitened variance `c`; unchecked blocks are `c I` until one is not.
    let c = match blocks.points(rows) {
        0 => 0.0,
        _ => first_whitened_variance(v, blocks, estimator)?,
    };
    let multiple = AtomicBool::new(c > 0.0);
    on_parts(blocks, rows, column_parts(&mut s, &bounds), |k, at, s| {
        let r = blocks.range(k);
        let (out, check) = ((at, &mut s[..]), (c, &multiple));
        match r.len() {
            3 => weigh_block(v, (r.start, Const::<3>), (estimator, k), out, check),
            6 => weigh_block(v, (r.start, Const::<6>), (estimator, k), out, check),
            n => weigh_block(v, (r.start, Dyn(n)), (estimator, k), out, check),
        }
    })?;
    if multiple.into_inner() {
        return Ok((s, RowCovariance::Scale(c)));
    }
    let mut noise = DMatrix::zeros(rows, width);
    on_parts(blocks, rows, column_parts(&mut noise, &bounds), |k, at, noise| {
        let r = blocks.range(k);
        match r.len() {
            3 => write_block(&whiten_block(v, &s, (r.start, Const::<3>)), at, noise),
            6 => write_block(&whiten_block(v, &s, (r.start, Const::<6>)), at, noise),
            n => write_block(&whiten_block(v, &s, (r.start, Dyn(n))), at, noise),
        }
        Ok(())
    })?;
    Ok((s, RowCovariance::Blocks(noise)))
}

/// `S_0 V_0 S_0^T`'s first element: the whitened variance every block is compared with.
fn first_whitened_variance(
    v: &DMatrix<f64>,
    blocks: &Blocks,
    estimator: Estimator,
) -> Result<f64, EstimationError> {
    fn of<D: Dim>(v: &DMatrix<f64>, d: D, estimator: Estimator) -> Result<f64, EstimationError>
    where
        DefaultAllocator: Allocator<D, D> + Allocator<D>,
    {
        let (s_0, v_0) = block_whitener(v, 0, d, estimator, 0)?;
        Ok((&s_0 * v_0 * s_0.transpose())[(0, 0)])
    }
    match blocks.range(0).len() {
        3 => of(v, Const::<3>, estimator),
        6 => of(v, Const::<6>, estimator),
        n => of(v, Dyn(n), estimator),
    }
}

/// `each(k, at, piece)` of every point `k` of a system of `rows` rows laid out by `blocks`, on
/// rayon's threads in the parts of [`point_parts`], each part with its own `piece` (in order)
/// and `at` the row of point `k` in it: the first point's error, whatever the threads.
fn on_parts<T: Send>(
    blocks: &Blocks,
    rows: usize,
    pieces: Vec<T>,
    each: impl Fn(usize, usize, &mut T) -> Result<(), EstimationError> + Sync,
) -> Result<(), EstimationError> {
    let parts = point_parts(blocks, rows).0;
    let done: Vec<Result<(), EstimationError>> = (parts.into_par_iter().zip(pieces))
        .map(|(mut points, mut piece)| {
            let first = blocks.range(points.start).start;
            points.try_for_each(|k| each(k, blocks.range(k).start - first, &mut piece))
        })
        .collect();
    done.into_iter().collect()
}

/// Points in one task of the work on stacked blocks done on threads.
const PART_POINTS: usize = 2048;

/// The points of a system of `rows` rows laid out by `blocks`, in parts of [`PART_POINTS`]:
/// each part's points, and the rows where the parts start (then `rows`).
fn point_parts(blocks: &Blocks, rows: usize) -> (Vec<Range<usize>>, Vec<usize>) {
    let points = blocks.points(rows);
    let parts: Vec<Range<usize>> =
        (0..points).step_by(PART_POINTS).map(|p| p..(p + PART_POINTS).min(points)).collect();
    let bounds = parts.iter().map(|p| blocks.range(p.start).start).chain([rows]).collect();
    (parts, bounds)
}

/// `rows` cut at `bounds` ([`point_parts`]): piece `i` holds `bounds[i]..bounds[i + 1]`.
fn split_rows<'m>(rows: &'m mut [f64], bounds: &[usize]) -> Vec<&'m mut [f64]> {
    let mut rest = rows;
    let mut pieces = Vec::with_capacity(bounds.len().saturating_sub(1));
    for w in bounds.windows(2) {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(w[1] - w[0]);
        pieces.push(head);
        rest = tail;
    }
    pieces
}

/// The columns of `m` cut at the rows `bounds` ([`split_rows`]): part `i` holds rows
/// `bounds[i]..bounds[i + 1]` of every column, in order, so that parts of the stacked blocks
/// can be written on threads of their own.
fn column_parts<'m>(m: &'m mut DMatrix<f64>, bounds: &[usize]) -> Vec<Vec<&'m mut [f64]>> {
    let rows = m.nrows();
    let mut parts: Vec<Vec<&mut [f64]>> = bounds.windows(2).map(|_| Vec::new()).collect();
    for column in m.as_mut_slice().chunks_exact_mut(rows.max(1)) {
        for (part, piece) in parts.iter_mut().zip(split_rows(column, bounds)) {
            part.push(piece);
        }
    }
    parts
}

/// `S_k` of the block of `d` rows at row `start` of `v` (point `k`), written at row `at` of
/// the column parts `s` ([`column_parts`]); `multiple` cleared if `S_k V_k S_k^T` is not `c I`
/// (unless it is already).
fn weigh_block<D: Dim>(
    v: &DMatrix<f64>,
    (start, d): (usize, D),
    (estimator, k): (Estimator, usize),
    (at, s): (usize, &mut [&mut [f64]]),
    (c, multiple): (f64, &AtomicBool),
) -> Result<(), EstimationError>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let (s_k, v_k) = block_whitener(v, start, d, estimator, k)?;
    write_block(&s_k, at, s);
    if multiple.load(Ordering::Relaxed) && !is_multiple(&(&s_k * v_k * s_k.transpose()), c) {
        multiple.store(false, Ordering::Relaxed);
    }
    Ok(())
}

/// `S_k V_k S_k^T` of the block of `d` rows at row `start`, `S_k` read from the stacked `s`
/// where [`weigh_block`] wrote it.
fn whiten_block<D: Dim>(v: &DMatrix<f64>, s: &DMatrix<f64>, (start, d): (usize, D)) -> OMatrix<f64, D, D>
where
    DefaultAllocator: Allocator<D, D>,
{
    let s_k = OMatrix::<f64, D, D>::from_fn_generic(d, d, |i, j| s[(start + i, j)]);
    let v_k = OMatrix::<f64, D, D>::from_fn_generic(d, d, |i, j| v[(start + i, j)]);
    &s_k * v_k * s_k.transpose()
}

/// The square block `m` written at row `at` of the column parts `columns`.
fn write_block<D: Dim>(m: &OMatrix<f64, D, D>, at: usize, columns: &mut [&mut [f64]])
where
    DefaultAllocator: Allocator<D, D>,
{
    for (j, column) in columns.iter_mut().take(m.ncols()).enumerate() {
        for i in 0..m.nrows() {
            column[at + i] = m[(i, j)];
        }
    }
}

/// `S_k` of `estimator` and `V_k` of the block of `d` rows at row `start` of `v` (point `k`).
#[allow(clippy::type_complexity)]
fn block_whitener<D: Dim>(
    v: &DMatrix<f64>,
    start: usize,
    d: D,
    estimator: Estimator,
    k: usize,
) -> Result<(OMatrix<f64, D, D>, OMatrix<f64, D, D>), EstimationError>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let v_k = OMatrix::<f64, D, D>::from_fn_generic(d, d, |i, j| v[(start + i, j)]);
    let not_pd = || EstimationError::NotPositiveDefinite { point: k };
    let s_k = match estimator {
        Estimator::Ols => OMatrix::identity_generic(d, d),
        Estimator::Wls => {
            let l = v_k.clone().cholesky().ok_or_else(not_pd)?.unpack();
            let inverse = l.solve_lower_triangular(&OMatrix::identity_generic(d, d));
            inverse.filter(|m| m.iter().all(|v| v.is_finite())).ok_or_else(not_pd)?
        }
        Estimator::WlsDiag | Estimator::WlsSigma => {
            if v_k.diagonal().iter().any(|&d| d <= 0.0) {
                return Err(not_pd());
            }
            let power = if estimator == Estimator::WlsDiag { -0.5 } else { -0.25 };
            OMatrix::from_diagonal(&v_k.diagonal().map(|d| d.powf(power)))
        }
    };
    Ok((s_k, v_k))
}

/// `m` (`N_m` rows) times the block-diagonal matrix whose blocks are stacked in `stacked`
/// (laid out by `blocks`), in place: each block loaded once, no allocation for blocks of 3
/// and 6 rows.
pub(crate) fn block_diagonal_mul<C: Dim, St: StorageMut<f64, Dyn, C> + IsContiguous>(
    stacked: &DMatrix<f64>,
    blocks: &Blocks,
    m: &mut Matrix<f64, Dyn, C, St>,
) {
    let rows = m.nrows();
    let values = m.as_mut_slice();
    for k in 0..blocks.points(rows) {
        let range = blocks.range(k);
        let columns = values.chunks_exact_mut(rows.max(1)).map(|column| &mut column[range.clone()]);
        block_mul(stacked, range.start, range.len(), columns);
    }
}

/// The block of `size` rows at row `start` of the stacked `blocks` times each of `columns`
/// (one block's height each): blocks of one to four markers and of a pose on the stack, others
/// through one product vector for all the columns (`gemv`, the arithmetic of `block * column`).
pub(crate) fn block_mul<'c>(
    blocks: &DMatrix<f64>,
    start: usize,
    size: usize,
    columns: impl Iterator<Item = &'c mut [f64]>,
) {
    match size {
        3 => fixed_block_mul::<3>(blocks, start, columns),
        6 => fixed_block_mul::<6>(blocks, start, columns),
        9 => fixed_block_mul::<9>(blocks, start, columns),
        12 => fixed_block_mul::<12>(blocks, start, columns),
        b => {
            let block = blocks.view((start, 0), (b, b));
            let mut product = DVector::zeros(b);
            for column in columns {
                product.gemv(1.0, &block, &nalgebra::DVectorView::from_slice(column, b), 0.0);
                column.copy_from_slice(product.as_slice());
            }
        }
    }
}

/// [`block_mul`] with the block on the stack.
fn fixed_block_mul<'c, const B: usize>(
    blocks: &DMatrix<f64>,
    start: usize,
    columns: impl Iterator<Item = &'c mut [f64]>,
) {
    let block: SMatrix<f64, B, B> = blocks.fixed_view::<B, B>(start, 0).into_owned();
    for column in columns {
        let column: &mut [f64; B] = column.try_into().expect("a column of one block's height");
        let product = block * nalgebra::SVector::<f64, B>::from(*column);
        // Element by element, of a length known at compile time: no call to memmove.
        *column = product.into();
    }
}

/// `c` if every stacked block is `c I` to a relative 1e-9, `c > 0`.
pub(crate) fn identity_multiple(stacked: &DMatrix<f64>, blocks: &Blocks) -> Option<f64> {
    let c = *stacked.get((0, 0))?;
    let multiple = (0..blocks.points(stacked.nrows())).all(|k| is_multiple(&blocks.block(stacked, k), c));
    (c > 0.0 && multiple).then_some(c)
}

/// Whether the square block `m` is `c I` to a relative 1e-9: `|m_ij - c delta_ij| <= 1e-9 c`.
fn is_multiple<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(m: &Matrix<f64, R, C, S>, c: f64) -> bool {
    let close = |v: f64, target: f64| (v - target).abs() <= 1e-9 * c;
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| close(m[(i, j)], if i == j { c } else { 0.0 })))
}
