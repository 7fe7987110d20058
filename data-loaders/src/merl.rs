//! MERL `.binary` isotropic BRDF tables.
//!
//! Layout: three little-endian `i32` dimensions (90, 90, 180), then
//! 3 × 1,458,000 little-endian `f64`, channel-planar (all red, then all green,
//! then all blue). Within a channel, cell (iθh, iθd, iφd) is at
//! `iφd + 180·(iθd + 90·iθh)`.
//!
//! Stored values are physical values (1/sr) divided by [`MerlTable::SCALE`].
//! A negative value in any channel marks a missing sample (unmeasured or
//! below the horizon); negatives are kept as they are, never clamped.
//!
//! Each cell stands for the lower-edge node of its bin,
//! θh = (i/90)²·π/2, θd = j·π/180, φd = k·π/180 (see [`MerlTable::node_angles`]);
//! MERL's reader finds the cell of a query by truncation ([`MerlTable::lookup`]).

use std::f64::consts::{FRAC_PI_2, PI};
use std::io::Write;
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};

use crate::atomic::write_atomic;
use crate::error::LoadError;
use crate::geometry::{angles_of, directions_from_half_diff_sc, Angles};
use crate::planar;
use crate::samples::{MeasuredSample, MeasuredSamples};

/// A MERL table holding the file's own values (not scaled), channel-major.
#[derive(Clone, PartialEq)]
pub struct MerlTable {
    raw: Vec<f64>,
}

/// A summary; the 4.4 million values are not printed.
impl std::fmt::Debug for MerlTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MerlTable")
            .field("cells", &Self::CELLS)
            .field("valid_cells", &self.valid_cells())
            .finish_non_exhaustive()
    }
}

const HEADER_BYTES: usize = 12;

/// Lookup tolerance in bin units: a query this close below a bin's lower edge
/// counts as inside that bin, so exact node angles, which can round to just
/// below their edge, find their own cell.
const EDGE_TOLERANCE: f64 = 1e-9;

impl MerlTable {
    /// theta_h cells (square-root spaced).
    pub const RES_THETA_H: usize = 90;
    /// theta_d cells (1 degree each).
    pub const RES_THETA_D: usize = 90;
    /// phi_d cells over [0, pi) (reciprocity folds the rest).
    pub const RES_PHI_D: usize = 180;
    /// Cells per channel.
    pub const CELLS: usize = 1_458_000;
    /// Physical value (1/sr) = stored value × `SCALE[channel]`.
    pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
    /// Exact size of a MERL file.
    pub const FILE_BYTES: u64 = 12 + 3 * 1_458_000 * 8;
    /// The stored value written for a missing cell by [`MerlTable::from_fn`].
    pub const MISSING: f64 = -1.0;
    const DIMS: [i32; 3] = [90, 90, 180];

    /// Reads a MERL file. The size is checked before anything is allocated;
    /// see [`MerlTable::from_bytes`] for the other checks.
    pub fn read(path: &Path) -> Result<Self, LoadError> {
        let mut header = [0u8; HEADER_BYTES];
        let raw = planar::read_header_f64s(
            path,
            Self::FILE_BYTES,
            &mut header,
            "a MERL table (.binary)",
        )?;
        Self::check_header(&header, path)?;
        Self::check_finite(&raw, path)?;
        Ok(MerlTable { raw })
    }

    /// [`LoadError::BadHeader`] unless the header is 90 90 180.
    fn check_header(header: &[u8], path: &Path) -> Result<(), LoadError> {
        let mut dims = [0i32; 3];
        LittleEndian::read_i32_into(&header[..HEADER_BYTES], &mut dims);
        if dims != Self::DIMS {
            return Err(LoadError::BadHeader {
                path: path.to_path_buf(),
                dims,
            });
        }
        Ok(())
    }

    /// Decodes the bytes of a MERL file; `path` is only used in messages.
    ///
    /// Errors: [`LoadError::WrongSize`] unless exactly [`MerlTable::FILE_BYTES`]
    /// long, [`LoadError::BadHeader`] unless the header is 90 90 180,
    /// [`LoadError::NonFinite`] for the first NaN or infinite value.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, LoadError> {
        if bytes.len() as u64 != Self::FILE_BYTES {
            return Err(Self::wrong_size(path, bytes.len() as u64));
        }
        Self::check_header(bytes, path)?;
        let mut raw = vec![0.0; 3 * Self::CELLS];
        LittleEndian::read_f64_into(&bytes[HEADER_BYTES..], &mut raw);
        Self::check_finite(&raw, path)?;
        Ok(MerlTable { raw })
    }

    fn wrong_size(path: &Path, actual: u64) -> LoadError {
        LoadError::WrongSize {
            path: path.to_path_buf(),
            expected: Self::FILE_BYTES,
            actual,
        }
    }

    fn check_finite(raw: &[f64], path: &Path) -> Result<(), LoadError> {
        planar::check_finite(raw, Self::CELLS, path)
    }

    /// The file's bytes: byte-identical to the file an unchanged table was read from.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = vec![0u8; Self::FILE_BYTES as usize];
        LittleEndian::write_i32_into(&Self::DIMS, &mut bytes[..HEADER_BYTES]);
        LittleEndian::write_f64_into(&self.raw, &mut bytes[HEADER_BYTES..]);
        bytes
    }

    /// Writes the table atomically (see [`crate::atomic::write_atomic`]).
    ///
    /// Refuses with [`LoadError::NonFinite`] (and writes nothing) if the table
    /// holds a NaN or infinite value, since the file could not be read back;
    /// with [`LoadError::Exists`] if `path` exists and `overwrite` is false.
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<(), LoadError> {
        Self::check_finite(&self.raw, path)?;
        write_atomic(path, overwrite, |w: &mut dyn Write| {
            let mut header = [0u8; HEADER_BYTES];
            LittleEndian::write_i32_into(&Self::DIMS, &mut header);
            w.write_all(&header)?;
            planar::write_f64s(w, &self.raw)
        })
    }

    /// Tabulates `f(theta_h, theta_d, phi_d)` at every cell's lower-edge node
    /// ([`MerlTable::node_angles`]). `Some(rgb)` holds physical values (1/sr)
    /// and is stored divided by [`MerlTable::SCALE`]; `None` marks the cell
    /// missing ([`MerlTable::MISSING`] in all channels).
    ///
    /// Values are stored as given: a negative channel makes the cell read as
    /// missing, and a NaN or infinite value makes [`MerlTable::write`] fail.
    /// Runs in parallel over theta_h rows; each cell's value is `f`'s
    /// alone, so the table does not depend on the threads.
    pub fn from_fn(f: impl Fn(f64, f64, f64) -> Option<[f64; 3]> + Sync) -> Self {
        use rayon::prelude::*;
        let row = Self::RES_THETA_D * Self::RES_PHI_D;
        let rows: Vec<Vec<[f64; 3]>> = (0..Self::RES_THETA_H)
            .into_par_iter()
            .map(|i_th| {
                let mut out = Vec::with_capacity(row);
                for i_td in 0..Self::RES_THETA_D {
                    for i_pd in 0..Self::RES_PHI_D {
                        let (th, td, pd) = Self::node_angles(i_th, i_td, i_pd);
                        out.push(match f(th, td, pd) {
                            Some(rgb) => std::array::from_fn(|c| rgb[c] / Self::SCALE[c]),
                            None => [Self::MISSING; 3],
                        });
                    }
                }
                out
            })
            .collect();
        let mut raw = vec![0.0; 3 * Self::CELLS];
        for (i_th, values) in rows.iter().enumerate() {
            for (k, v) in values.iter().enumerate() {
                let idx = i_th * row + k;
                for (c, x) in v.iter().enumerate() {
                    raw[c * Self::CELLS + idx] = *x;
                }
            }
        }
        MerlTable { raw }
    }

    /// A table from stored (unscaled) values, channel-major as in the file.
    ///
    /// # Panics
    /// If `raw.len() != 3 * MerlTable::CELLS`. Values are not checked.
    pub fn from_raw(raw: Vec<f64>) -> Self {
        assert_eq!(
            raw.len(),
            3 * Self::CELLS,
            "a MERL table has 3 * {} values",
            Self::CELLS
        );
        MerlTable { raw }
    }

    /// The stored values, channel-major: `raw[c * CELLS + index]`.
    pub fn raw(&self) -> &[f64] {
        &self.raw
    }

    /// Cell index within a channel: `i_pd + 180 * (i_td + 90 * i_th)`.
    #[inline]
    pub fn index(i_th: usize, i_td: usize, i_pd: usize) -> usize {
        i_pd + Self::RES_PHI_D * (i_td + Self::RES_THETA_D * i_th)
    }

    /// The (theta_h, theta_d, phi_d) node a cell stands for, in radians:
    /// ((i/90)²·π/2, j·π/180, k·π/180).
    #[inline]
    pub fn node_angles(i_th: usize, i_td: usize, i_pd: usize) -> (f64, f64, f64) {
        let u = i_th as f64 / Self::RES_THETA_H as f64;
        (
            u * u * FRAC_PI_2,
            i_td as f64 * (PI / 180.0),
            i_pd as f64 * (PI / 180.0),
        )
    }

    /// Physical RGB (1/sr) of a cell, or `None` if any channel is negative.
    ///
    /// # Panics
    /// If `index >= MerlTable::CELLS`.
    #[inline]
    pub fn cell(&self, index: usize) -> Option<[f64; 3]> {
        assert!(index < Self::CELLS, "MERL cell index {index} out of range");
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let v = self.raw[c * Self::CELLS + index];
            if v < 0.0 {
                return None;
            }
            *o = v * Self::SCALE[c];
        }
        Some(out)
    }

    /// MERL's truncating lookup: the cell whose bin contains the query, its
    /// physical RGB, or `None` if that cell is missing or an angle is NaN.
    ///
    /// iθh = ⌊√(θh/(π/2))·90⌋ (0 for θh ≤ 0), iθd = ⌊θd/(π/2)·90⌋,
    /// iφd = ⌊φd/π·180⌋ after adding π to a negative φd; each index is
    /// clamped to its range. One deviation from the reference reader: a query
    /// within 1e-9 bin widths below a bin edge counts as in that bin, so
    /// `lookup` at [`MerlTable::node_angles`] returns that node's cell.
    pub fn lookup(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> Option<[f64; 3]> {
        let (x_th, x_td, x_pd) = Self::index_coords(theta_h, theta_d, phi_d)?;
        self.cell(Self::index(
            bin(x_th, Self::RES_THETA_H),
            bin(x_td, Self::RES_THETA_D),
            bin(x_pd, Self::RES_PHI_D),
        ))
    }

    /// Continuous index coordinates of a query, nodes at the integers:
    /// (sqrt(theta_h / (pi/2)) 90 (0 for theta_h <= 0), theta_d / (pi/2) 90,
    /// phi_d / pi 180 after adding pi to a negative phi_d); `None` for a NaN
    /// angle. Both readers start from them.
    fn index_coords(theta_h: f64, theta_d: f64, phi_d: f64) -> Option<(f64, f64, f64)> {
        if theta_h.is_nan() || theta_d.is_nan() || phi_d.is_nan() {
            return None;
        }
        let x_th = if theta_h <= 0.0 {
            0.0
        } else {
            (theta_h / FRAC_PI_2).sqrt() * Self::RES_THETA_H as f64
        };
        let x_td = theta_d / FRAC_PI_2 * Self::RES_THETA_D as f64;
        let pd = if phi_d < 0.0 { phi_d + PI } else { phi_d };
        Some((x_th, x_td, pd / PI * Self::RES_PHI_D as f64))
    }

    /// The value at (theta_h, theta_d, phi_d) interpolated between the
    /// lower-edge nodes ([`MerlTable::node_angles`]): multilinear in the
    /// index coordinates (sqrt(theta_h) scaled, theta_d, phi_d), phi_d
    /// periodic with period pi (the fold [`MerlTable::lookup`] applies),
    /// the other two held at their last node. The reading that treats each
    /// cell as the BRDF *at* its node (the convention the tables are made
    /// with); `lookup` holds a node's value across its whole bin instead,
    /// which raises a sharp lobe's energy. Missing corners are left out and
    /// the others' weights renormalised; `None` if all are missing or an
    /// angle is NaN.
    pub fn lookup_interpolated(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> Option<[f64; 3]> {
        let (x_th, x_td, x_pd) = Self::index_coords(theta_h, theta_d, phi_d)?;
        let x_td = x_td.max(0.0);
        let x_pd = x_pd.rem_euclid(Self::RES_PHI_D as f64);
        // (lower node, upper node, weight of the upper one) on a held axis
        let held = |x: f64, n: usize| {
            let last = (n - 1) as f64;
            if x >= last {
                (n - 1, n - 1, 0.0)
            } else {
                let f = x.floor();
                (f as usize, f as usize + 1, x - f)
            }
        };
        let (h0, h1, wh) = held(x_th, Self::RES_THETA_H);
        let (d0, d1, wd) = held(x_td, Self::RES_THETA_D);
        let f = x_pd.floor();
        let p0 = (f as usize).min(Self::RES_PHI_D - 1);
        let (p1, wp) = ((p0 + 1) % Self::RES_PHI_D, x_pd - f);
        let mut acc = [0.0; 3];
        let mut total = 0.0;
        for (ih, a) in [(h0, 1.0 - wh), (h1, wh)] {
            for (id, b) in [(d0, 1.0 - wd), (d1, wd)] {
                for (ip, c) in [(p0, 1.0 - wp), (p1, wp)] {
                    let w = a * b * c;
                    if w <= 0.0 {
                        continue;
                    }
                    if let Some(v) = self.cell(Self::index(ih, id, ip)) {
                        total += w;
                        for k in 0..3 {
                            acc[k] += w * v[k];
                        }
                    }
                }
            }
        }
        (total > 0.0).then(|| acc.map(|v| v / total))
    }

    /// Number of cells with no negative channel.
    pub fn valid_cells(&self) -> usize {
        let (r, rest) = self.raw.split_at(Self::CELLS);
        let (g, b) = rest.split_at(Self::CELLS);
        r.iter()
            .zip(g)
            .zip(b)
            .filter(|((r, g), b)| **r >= 0.0 && **g >= 0.0 && **b >= 0.0)
            .count()
    }

    /// The valid cells whose node is above the horizon (cos θi > 0 and
    /// cos θo > 0, with φh = 0), as samples at the node angles with physical
    /// RGB. Missing cells and below-horizon cells are counted in `missing`,
    /// so `samples.len() + missing == CELLS`. Samples are in cell order.
    ///
    /// Two passes over the θh rows in parallel (rayon's current pool): one
    /// counts each row's samples, the other writes them into the row's own
    /// part of a vector of exactly the final size, so the result is the same
    /// for any thread count and no larger buffer is ever held. The sines and
    /// cosines of the grid's 360 distinct angles are computed once; every
    /// sample's arithmetic is otherwise that of `Angles::from_half_diff`.
    pub fn samples(&self, source: &str) -> MeasuredSamples {
        use rayon::prelude::*;
        let trig = NodeTrig::new();
        let counts: Vec<usize> = (0..Self::RES_THETA_H)
            .into_par_iter()
            .map(|i_th| self.row_cells(&trig, i_th, |_, _, _, _| {}))
            .collect();
        let total: usize = counts.iter().sum();
        let mut samples: Vec<MeasuredSample> = Vec::with_capacity(total);
        let mut rows = Vec::with_capacity(Self::RES_THETA_H);
        let mut rest = &mut samples.spare_capacity_mut()[..total];
        for &n in &counts {
            let (row, tail) = rest.split_at_mut(n);
            rows.push(row);
            rest = tail;
        }
        rows.into_par_iter().enumerate().for_each(|(i_th, row)| {
            let mut at = 0;
            let written = self.row_cells(&trig, i_th, |angles, rgb, wi, wo| {
                row[at].write(sample_of(angles, rgb, wi, wo));
                at += 1;
            });
            assert_eq!(written, row.len(), "the two passes over a row disagree");
        });
        // SAFETY: every row's slots were written above (the assertion checks
        // each row's count), and the rows tile the first `total` slots.
        unsafe { samples.set_len(total) };
        MeasuredSamples {
            source: source.to_string(),
            isotropic: true,
            samples,
            missing: Self::CELLS - total,
        }
    }

    /// The samples of [`MerlTable::samples`], the same values in the same
    /// order, in consecutive pieces of `chunk` (the last may be shorter):
    /// `f` of each piece, in piece order. The pieces are made and consumed
    /// in parallel (rayon's current pool), one at a time per worker, so the
    /// samples are never all held (a pass over them costs no 128 MB of
    /// fresh memory); the result is the same for any thread count.
    ///
    /// # Panics
    /// If `chunk` is 0.
    pub fn map_sample_chunks<R: Send>(
        &self,
        chunk: usize,
        f: impl Fn(&[MeasuredSample]) -> R + Sync,
    ) -> Vec<R> {
        self.map_cell_pieces(
            chunk,
            || Vec::with_capacity(chunk),
            |piece: &mut Vec<MeasuredSample>, cells| {
                piece.clear();
                cells.for_each(|c| piece.push(c.sample()));
                f(piece)
            },
        )
    }

    /// The cells behind [`MerlTable::map_sample_chunks`]' pieces, not made
    /// into samples: `f(scratch, piece)` of each consecutive piece of
    /// `chunk` sample cells, in piece order, computed in parallel (rayon's
    /// current pool) with one `scratch` from `init` per worker. For callers
    /// that use the grid's structure (a θh, θd row's 180 cells share their
    /// half and difference elevations) and skip the azimuths.
    ///
    /// # Panics
    /// If `chunk` is 0.
    pub fn map_cell_pieces<T, R: Send>(
        &self,
        chunk: usize,
        init: impl Fn() -> T + Sync + Send,
        f: impl Fn(&mut T, CellPiece<'_>) -> R + Sync,
    ) -> Vec<R> {
        use rayon::prelude::*;
        assert!(chunk > 0, "pieces of at least one sample");
        let trig = NodeTrig::new();
        // Each row's sample cells (i_td * 180 + i_pd, below 2^16).
        let rows: Vec<Vec<u16>> = (0..Self::RES_THETA_H)
            .into_par_iter()
            .map(|i_th| {
                let mut cells = Vec::new();
                self.row_cells_at(
                    &trig,
                    i_th,
                    0..Self::RES_THETA_D * Self::RES_PHI_D,
                    |at, _, _, _, _| cells.push(at as u16),
                );
                cells
            })
            .collect();
        let mut starts = Vec::with_capacity(rows.len() + 1);
        starts.push(0);
        for r in &rows {
            starts.push(starts.last().copied().unwrap_or(0) + r.len());
        }
        let total = starts[rows.len()];
        (0..total.div_ceil(chunk))
            .into_par_iter()
            .map_init(init, |scratch, c| {
                let (lo, hi) = (c * chunk, (c * chunk + chunk).min(total));
                let piece = CellPiece {
                    table: self,
                    trig: &trig,
                    rows: &rows,
                    starts: &starts,
                    lo,
                    hi,
                };
                f(scratch, piece)
            })
            .collect()
    }

    /// Calls `sample(angles, rgb, wi, wo)` for each valid, above-horizon cell
    /// of θh row `i_th` in cell order (`angles` holds the half/difference
    /// angles only) and returns how many there were.
    #[inline(always)]
    fn row_cells(
        &self,
        trig: &NodeTrig,
        i_th: usize,
        mut sample: impl FnMut(Angles, [f64; 3], [f64; 3], [f64; 3]),
    ) -> usize {
        let mut n = 0;
        self.row_cells_at(
            trig,
            i_th,
            0..Self::RES_THETA_D * Self::RES_PHI_D,
            |_, angles, rgb, wi, wo| {
                sample(angles, rgb, wi, wo);
                n += 1;
            },
        );
        n
    }

    /// [`MerlTable::row_cells`] over the cells `cells` of the row only
    /// (numbered i_td * 180 + i_pd), each sample's number passed first.
    #[inline(always)]
    fn row_cells_at(
        &self,
        trig: &NodeTrig,
        i_th: usize,
        cells: std::ops::Range<usize>,
        mut sample: impl FnMut(usize, Angles, [f64; 3], [f64; 3], [f64; 3]),
    ) {
        let sc_th = trig.theta_h[i_th];
        let sc_0 = trig.zero;
        for at in cells {
            let (i_td, i_pd) = (at / Self::RES_PHI_D, at % Self::RES_PHI_D);
            let index = Self::index(i_th, i_td, i_pd);
            // As [`MerlTable::cell`]: missing if any channel is negative.
            if (0..3).any(|c| self.raw[c * Self::CELLS + index] < 0.0) {
                continue;
            }
            let (wi, wo) =
                directions_from_half_diff_sc(sc_th, sc_0, trig.theta_d[i_td], trig.phi_d[i_pd]);
            if wi[2] <= 0.0 || wo[2] <= 0.0 {
                continue;
            }
            let (th, td, pd) = Self::node_angles(i_th, i_td, i_pd);
            let rgb = std::array::from_fn(|c| self.raw[c * Self::CELLS + index] * Self::SCALE[c]);
            sample(at, node_half_diff(th, td, pd), rgb, wi, wo);
        }
    }
}

/// A MERL table's valid samples without their 88-byte records: for each
/// sample of [`MerlTable::samples`] (same count, same order), its cell and
/// its two elevations, 20 bytes. What a fit reads of a MERL table (the
/// angles a weight or a stencil needs) is the grid's, by index arithmetic;
/// the elevations are the one per-sample transcendental part, computed once.
/// [`MerlSamples::sample`] makes any sample's record, bit for bit the one
/// `samples` makes.
pub struct MerlSamples {
    table: MerlTable,
    source: String,
    trig: NodeTrig,
    /// Each sample's cell index ([`MerlTable::index`]).
    cell: Vec<u32>,
    /// Each sample's (theta_i, theta_o), as `Angles::from_half_diff`.
    theta: Vec<[f64; 2]>,
    /// Grid row r = i_th * 90 + i_td holds samples `row_start[r]..row_start[r + 1]`.
    row_start: Vec<u32>,
}

impl std::fmt::Debug for MerlSamples {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MerlSamples")
            .field("source", &self.source)
            .field("samples", &self.cell.len())
            .finish_non_exhaustive()
    }
}

/// Grid rows (theta_h, theta_d pairs) of a MERL table.
pub const MERL_ROWS: usize = MerlTable::RES_THETA_H * MerlTable::RES_THETA_D;

impl MerlSamples {
    /// The valid, above-horizon cells of `table` (as [`MerlTable::samples`]),
    /// found in parallel over the theta_h rows (rayon's current pool): a
    /// counting pass, then each row writes its own part of arrays of the
    /// final size, so the result is the same for any thread count.
    pub fn new(table: MerlTable, source: &str) -> Self {
        use rayon::prelude::*;
        let trig = NodeTrig::new();
        let per_row = MerlTable::RES_THETA_D * MerlTable::RES_PHI_D;
        // Samples per (theta_h, theta_d) row.
        let counts: Vec<[u32; MerlTable::RES_THETA_D]> = (0..MerlTable::RES_THETA_H)
            .into_par_iter()
            .map(|i_th| {
                let mut n = [0u32; MerlTable::RES_THETA_D];
                table.row_cells_at(&trig, i_th, 0..per_row, |at, _, _, _, _| {
                    n[at / MerlTable::RES_PHI_D] += 1
                });
                n
            })
            .collect();
        let mut row_start = Vec::with_capacity(MERL_ROWS + 1);
        row_start.push(0u32);
        for n in counts.iter().flatten() {
            row_start.push(row_start[row_start.len() - 1] + n);
        }
        let total = row_start[MERL_ROWS] as usize;
        let mut cell = vec![0u32; total];
        let mut theta = vec![[0.0; 2]; total];
        let mut pieces = Vec::with_capacity(MerlTable::RES_THETA_H);
        let (mut c_rest, mut t_rest) = (&mut cell[..], &mut theta[..]);
        for i_th in 0..MerlTable::RES_THETA_H {
            let n = (row_start[(i_th + 1) * MerlTable::RES_THETA_D]
                - row_start[i_th * MerlTable::RES_THETA_D]) as usize;
            let (c, c_tail) = c_rest.split_at_mut(n);
            let (t, t_tail) = t_rest.split_at_mut(n);
            pieces.push((c, t));
            (c_rest, t_rest) = (c_tail, t_tail);
        }
        pieces
            .into_par_iter()
            .enumerate()
            .for_each(|(i_th, (c, t))| {
                let mut k = 0;
                table.row_cells_at(&trig, i_th, 0..per_row, |at, _, _, wi, wo| {
                    c[k] = (i_th * per_row + at) as u32;
                    t[k] = [elevation(wi), elevation(wo)];
                    k += 1;
                });
                assert_eq!(k, c.len(), "the two passes over a row disagree");
            });
        MerlSamples {
            table,
            source: source.to_string(),
            trig,
            cell,
            theta,
            row_start,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.cell.len()
    }

    /// Whether the table has no valid sample.
    pub fn is_empty(&self) -> bool {
        self.cell.is_empty()
    }

    /// Where the samples came from, for messages.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The table.
    pub fn table(&self) -> &MerlTable {
        &self.table
    }

    /// The table, the samples' arrays freed.
    pub fn into_table(self) -> MerlTable {
        self.table
    }

    /// Sample i's cell ([`MerlTable::index`]).
    #[inline]
    pub fn cell(&self, i: usize) -> usize {
        self.cell[i] as usize
    }

    /// Sample i's (theta_i, theta_o).
    #[inline]
    pub fn theta(&self, i: usize) -> [f64; 2] {
        self.theta[i]
    }

    /// Sample i's (theta_h, theta_d), its node's.
    #[inline]
    pub fn half_diff(&self, i: usize) -> (f64, f64) {
        let (i_th, i_td, i_pd) = split_cell(self.cell(i));
        let (th, td, _) = MerlTable::node_angles(i_th, i_td, i_pd);
        (th, td)
    }

    /// Sample i's physical RGB (1/sr).
    #[inline]
    pub fn rgb(&self, i: usize) -> [f64; 3] {
        let at = self.cell(i);
        std::array::from_fn(|c| self.table.raw[c * MerlTable::CELLS + at] * MerlTable::SCALE[c])
    }

    /// The samples of grid row `row` (i_th * 90 + i_td).
    #[inline]
    pub fn row(&self, row: usize) -> std::ops::Range<usize> {
        self.row_start[row] as usize..self.row_start[row + 1] as usize
    }

    /// Sample i's (wi, wo), as [`MerlTable::samples`] computes them.
    #[inline]
    pub fn directions(&self, i: usize) -> ([f64; 3], [f64; 3]) {
        let (i_th, i_td, i_pd) = split_cell(self.cell(i));
        directions_from_half_diff_sc(
            self.trig.theta_h[i_th],
            self.trig.zero,
            self.trig.theta_d[i_td],
            self.trig.phi_d[i_pd],
        )
    }

    /// Sample i's record, exactly as [`MerlTable::samples`] makes it.
    pub fn sample(&self, i: usize) -> MeasuredSample {
        let (i_th, i_td, i_pd) = split_cell(self.cell(i));
        let (th, td, pd) = MerlTable::node_angles(i_th, i_td, i_pd);
        let (wi, wo) = self.directions(i);
        sample_of(node_half_diff(th, td, pd), self.rgb(i), wi, wo)
    }

    /// Cells of the table that are not samples (missing or below the horizon).
    pub fn missing(&self) -> usize {
        MerlTable::CELLS - self.len()
    }
}

/// A direction's elevation, `angles_of(v).0` bit for bit without its
/// azimuth: an atan2 a sample that `MerlSamples::new` would throw away.
#[inline(always)]
fn elevation(v: [f64; 3]) -> f64 {
    v[2].clamp(-1.0, 1.0).acos()
}

/// (i_th, i_td, i_pd) of a cell index.
#[inline]
fn split_cell(at: usize) -> (usize, usize, usize) {
    let (row, i_pd) = (at / MerlTable::RES_PHI_D, at % MerlTable::RES_PHI_D);
    (
        row / MerlTable::RES_THETA_D,
        row % MerlTable::RES_THETA_D,
        i_pd,
    )
}

/// A consecutive run of sample cells ([`MerlTable::map_cell_pieces`]).
pub struct CellPiece<'a> {
    table: &'a MerlTable,
    trig: &'a NodeTrig,
    rows: &'a [Vec<u16>],
    starts: &'a [usize],
    lo: usize,
    hi: usize,
}

impl CellPiece<'_> {
    /// Number of sample cells in the piece.
    pub fn len(&self) -> usize {
        self.hi - self.lo
    }

    /// True for a piece of no cells.
    pub fn is_empty(&self) -> bool {
        self.hi == self.lo
    }

    /// Calls `visit` for each of the piece's cells, in sample order.
    #[inline]
    pub fn for_each(&self, mut visit: impl FnMut(SampleCell)) {
        let (lo, hi) = (self.lo, self.hi);
        // The row holding sample `lo`, then rows until `hi`.
        let mut i_th = self.starts.partition_point(|&s| s <= lo) - 1;
        let mut from = lo - self.starts[i_th];
        let mut done = 0;
        while done < hi - lo {
            let row = &self.rows[i_th];
            let want = (hi - lo - done).min(row.len() - from);
            for &at in &row[from..from + want] {
                let at = at as usize;
                self.table
                    .row_cells_at(self.trig, i_th, at..at + 1, |_, angles, rgb, wi, wo| {
                        visit(SampleCell {
                            i_th,
                            i_td: at / MerlTable::RES_PHI_D,
                            angles,
                            rgb,
                            wi,
                            wo,
                        })
                    });
            }
            done += want;
            (i_th, from) = (i_th + 1, 0);
        }
    }
}

/// One sample cell of a [`CellPiece`]: what its [`MeasuredSample`] is made
/// from.
#[derive(Clone, Copy, Debug)]
pub struct SampleCell {
    /// The theta_h row.
    pub i_th: usize,
    /// The theta_d row.
    pub i_td: usize,
    /// The node's half and difference angles (theta_h, theta_d, phi_d;
    /// phi_h = 0); the elevations and azimuths of wi and wo are 0 here.
    pub angles: Angles,
    /// Physical RGB (1/sr).
    pub rgb: [f64; 3],
    /// The light direction (both above the horizon).
    pub wi: [f64; 3],
    /// The view direction.
    pub wo: [f64; 3],
}

impl SampleCell {
    /// The cell's sample, as [`MerlTable::samples`] makes it.
    #[inline]
    pub fn sample(&self) -> MeasuredSample {
        sample_of(self.angles, self.rgb, self.wi, self.wo)
    }
}

/// A node's half and difference angles (phi_h = 0), its elevations and
/// azimuths left 0 for [`sample_of`].
#[inline(always)]
fn node_half_diff(theta_h: f64, theta_d: f64, phi_d: f64) -> Angles {
    Angles {
        theta_h,
        phi_h: 0.0,
        theta_d,
        phi_d,
        theta_i: 0.0,
        phi_i: 0.0,
        theta_o: 0.0,
        phi_o: 0.0,
    }
}

/// A sample from `row_cells`' arguments: `Angles::from_half_diff`'s
/// elevations and azimuths, from the directions already at hand.
#[inline(always)]
fn sample_of(angles: Angles, rgb: [f64; 3], wi: [f64; 3], wo: [f64; 3]) -> MeasuredSample {
    let ((theta_i, phi_i), (theta_o, phi_o)) = (angles_of(wi), angles_of(wo));
    let angles = Angles {
        theta_i,
        phi_i,
        theta_o,
        phi_o,
        ..angles
    };
    MeasuredSample { angles, rgb }
}

/// (sin, cos) of every node angle of the MERL grid (and of φh = 0).
struct NodeTrig {
    theta_h: Vec<(f64, f64)>,
    theta_d: Vec<(f64, f64)>,
    phi_d: Vec<(f64, f64)>,
    zero: (f64, f64),
}

impl NodeTrig {
    fn new() -> Self {
        let node = |i_th, i_td, i_pd| MerlTable::node_angles(i_th, i_td, i_pd);
        NodeTrig {
            theta_h: (0..MerlTable::RES_THETA_H)
                .map(|i| node(i, 0, 0).0.sin_cos())
                .collect(),
            theta_d: (0..MerlTable::RES_THETA_D)
                .map(|i| node(0, i, 0).1.sin_cos())
                .collect(),
            phi_d: (0..MerlTable::RES_PHI_D)
                .map(|i| node(0, 0, i).2.sin_cos())
                .collect(),
            zero: 0f64.sin_cos(),
        }
    }
}

/// ⌊x⌋ (with [`EDGE_TOLERANCE`]) clamped to `0..n`.
#[inline]
fn bin(x: f64, n: usize) -> usize {
    let f = (x + EDGE_TOLERANCE).floor();
    if f <= 0.0 {
        0
    } else if f >= (n - 1) as f64 {
        n - 1
    } else {
        f as usize
    }
}

#[cfg(test)]
mod tests;

/// Property: any mutation of a valid file (bytes overwritten, the file cut
/// or extended) is refused with a typed error or, if it is still a table,
/// writes back byte for byte; never a panic.
#[cfg(test)]
mod prop {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    fn valid() -> &'static [u8] {
        static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
        BYTES.get_or_init(|| {
            MerlTable::from_fn(|th, td, _| (td < 1.5).then_some([th + 0.1, td + 0.2, 0.3]))
                .to_bytes()
        })
    }

    proptest! {
        // A case copies and parses 35 MB: few cases, many mutations each.
        #![proptest_config(ProptestConfig::with_cases(12))]
        #[test]
        fn mutated_tables_are_refused_or_round_trip(
            edits in proptest::collection::vec((any::<u64>(), any::<u8>()), 0..64),
            cut in prop_oneof![Just(None), (0u64..64).prop_map(Some)],
            extend in 0usize..3,
        ) {
            let mut b = valid().to_vec();
            for (at, v) in edits {
                let i = (at % b.len() as u64) as usize;
                b[i] = v;
            }
            if let Some(c) = cut {
                b.truncate(b.len() - 1 - c as usize);
            }
            b.extend(std::iter::repeat(0u8).take(extend));
            match MerlTable::from_bytes(&b, Path::new("p.binary")) {
                Ok(t) => prop_assert_eq!(t.to_bytes(), b),
                Err(e) => prop_assert!(e.to_string().starts_with("p.binary: "), "{}", e),
            }
        }
    }
}
