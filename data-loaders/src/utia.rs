//! UTIA anisotropic BRDF tables (Filip & Vávra 2014), `.bin` files.
//!
//! Layout: no header, 3 × 82,944 little-endian `f64`, channel-planar (all
//! red, then all green, then all blue). Within a channel the illumination
//! direction is the major axis: cell (iθi, iφi, iθv, iφv) is at
//! `288·(48·iθi + iφi) + 48·iθv + iφv`, with θ = 0°, 15°, …, 75° and
//! φ = 0°, 7.5°, …, 352.5°.
//!
//! # Colour and scale convention
//!
//! The published loaders disagree (sRGB-decoded, or scaled by 1/140 then
//! gamma-decoded, or raw). This crate uses the **raw values as linear RGB,
//! unscaled**: [`UtiaTable::cell`] and [`UtiaTable::samples`] return exactly
//! the stored numbers. They are in the database's own units, which are not
//! checked to be 1/sr. A cell with a negative value in any channel is missing
//! (negatives are kept in the table, never clamped). Results on UTIA data are
//! therefore comparable only with other results using this convention.
//!
//! At θ = 0 all 48 φ values of a direction are the same physical direction;
//! the file stores 48 measurements there and [`UtiaTable::samples`] keeps
//! them all.

use std::f64::consts::PI;
use std::io::Write;
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};

use crate::atomic::write_atomic;
use crate::error::LoadError;
use crate::geometry::{spherical, Angles};
use crate::planar;
use crate::samples::{MeasuredSample, MeasuredSamples};

/// A UTIA table holding the file's own values, channel-major.
#[derive(Clone, PartialEq)]
pub struct UtiaTable {
    raw: Vec<f64>,
}

/// A summary; the values are not printed.
impl std::fmt::Debug for UtiaTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("UtiaTable")
            .field("cells", &Self::CELLS)
            .field("valid_cells", &self.valid_cells())
            .finish_non_exhaustive()
    }
}

impl UtiaTable {
    /// Elevations per direction (0°..75°).
    pub const N_THETA: usize = 6;
    /// Azimuths per direction (0°..352.5°).
    pub const N_PHI: usize = 48;
    /// Elevation step (degrees).
    pub const THETA_STEP_DEG: f64 = 15.0;
    /// Azimuth step (degrees).
    pub const PHI_STEP_DEG: f64 = 7.5;
    /// Cells per channel: 6 · 48 · 6 · 48.
    pub const CELLS: usize = 82_944;
    /// Exact size of a UTIA file.
    pub const FILE_BYTES: u64 = 3 * 82_944 * 8;
    /// The stored value written for a missing cell by [`UtiaTable::from_fn`].
    pub const MISSING: f64 = -1.0;

    /// Reads a UTIA `.bin` file; see [`UtiaTable::from_bytes`] for the checks.
    pub fn read(path: &Path) -> Result<Self, LoadError> {
        let bytes = planar::read_exact_size_as(path, Self::FILE_BYTES, "a UTIA table (.bin)")?;
        Self::from_bytes(&bytes, path)
    }

    /// Decodes the bytes of a UTIA file; `path` is only used in messages.
    ///
    /// Errors: [`LoadError::WrongSize`] unless exactly
    /// [`UtiaTable::FILE_BYTES`] long, [`LoadError::NonFinite`] for the first
    /// NaN or infinite value.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, LoadError> {
        if bytes.len() as u64 != Self::FILE_BYTES {
            return Err(LoadError::WrongSize {
                path: path.to_path_buf(),
                expected: Self::FILE_BYTES,
                actual: bytes.len() as u64,
            });
        }
        let mut raw = vec![0.0; 3 * Self::CELLS];
        LittleEndian::read_f64_into(bytes, &mut raw);
        planar::check_finite(&raw, Self::CELLS, path)?;
        Ok(UtiaTable { raw })
    }

    /// The file's bytes: byte-identical to the file an unchanged table was read from.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = vec![0u8; Self::FILE_BYTES as usize];
        LittleEndian::write_f64_into(&self.raw, &mut bytes);
        bytes
    }

    /// Writes the table atomically (see [`crate::atomic::write_atomic`]).
    /// Refuses with [`LoadError::NonFinite`] if a value is NaN or infinite,
    /// with [`LoadError::Exists`] if `path` exists and `overwrite` is false.
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<(), LoadError> {
        planar::check_finite(&self.raw, Self::CELLS, path)?;
        write_atomic(path, overwrite, |w: &mut dyn Write| {
            planar::write_f64s(w, &self.raw)
        })
    }

    /// Tabulates `f(theta_i, phi_i, theta_v, phi_v)` (radians) at every cell.
    /// `Some(rgb)` is stored as given (see the module's colour convention);
    /// `None` marks the cell missing ([`UtiaTable::MISSING`] in all channels).
    /// Runs serially.
    pub fn from_fn(f: impl Fn(f64, f64, f64, f64) -> Option<[f64; 3]> + Sync) -> Self {
        let mut raw = vec![0.0; 3 * Self::CELLS];
        let n = Self::N_THETA;
        let m = Self::N_PHI;
        for (i_ti, i_pi, i_tv, i_pv) in grid(n, m) {
            let (ti, pi, tv, pv) = Self::node_angles(i_ti, i_pi, i_tv, i_pv);
            let idx = Self::index(i_ti, i_pi, i_tv, i_pv);
            let v = f(ti, pi, tv, pv).unwrap_or([Self::MISSING; 3]);
            for (c, x) in v.into_iter().enumerate() {
                raw[c * Self::CELLS + idx] = x;
            }
        }
        UtiaTable { raw }
    }

    /// A table from stored values, channel-major as in the file.
    ///
    /// # Panics
    /// If `raw.len() != 3 * UtiaTable::CELLS`. Values are not checked.
    pub fn from_raw(raw: Vec<f64>) -> Self {
        assert_eq!(
            raw.len(),
            3 * Self::CELLS,
            "a UTIA table has 3 * {} values",
            Self::CELLS
        );
        UtiaTable { raw }
    }

    /// The stored values, channel-major: `raw[c * CELLS + index]`.
    pub fn raw(&self) -> &[f64] {
        &self.raw
    }

    /// Cell index within a channel: `288·(48·i_ti + i_pi) + 48·i_tv + i_pv`.
    #[inline]
    pub fn index(i_ti: usize, i_pi: usize, i_tv: usize, i_pv: usize) -> usize {
        let row = Self::N_THETA * Self::N_PHI;
        row * (Self::N_PHI * i_ti + i_pi) + Self::N_PHI * i_tv + i_pv
    }

    /// (theta_i, phi_i, theta_v, phi_v) of a cell, in radians.
    #[inline]
    pub fn node_angles(i_ti: usize, i_pi: usize, i_tv: usize, i_pv: usize) -> (f64, f64, f64, f64) {
        let t = Self::THETA_STEP_DEG * PI / 180.0;
        let p = Self::PHI_STEP_DEG * PI / 180.0;
        (
            i_ti as f64 * t,
            i_pi as f64 * p,
            i_tv as f64 * t,
            i_pv as f64 * p,
        )
    }

    /// Stored RGB of a cell, or `None` if any channel is negative.
    ///
    /// # Panics
    /// If `index >= UtiaTable::CELLS`.
    #[inline]
    pub fn cell(&self, index: usize) -> Option<[f64; 3]> {
        assert!(index < Self::CELLS, "UTIA cell index {index} out of range");
        let rgb = [
            self.raw[index],
            self.raw[Self::CELLS + index],
            self.raw[2 * Self::CELLS + index],
        ];
        rgb.iter().all(|v| *v >= 0.0).then_some(rgb)
    }

    /// Quadrilinear interpolation at any (theta_i, phi_i, theta_v, phi_v)
    /// (radians), as UTIA's own reader does: linear in each elevation on the
    /// 15-degree nodes (clamped to [0, 75] degrees, so directions past the
    /// last node take its values), linear and periodic in each azimuth on
    /// the 7.5-degree nodes. Missing cells count as zero.
    pub fn interpolate(&self, theta_i: f64, phi_i: f64, theta_v: f64, phi_v: f64) -> [f64; 3] {
        let t_step = Self::THETA_STEP_DEG.to_radians();
        let p_step = Self::PHI_STEP_DEG.to_radians();
        let theta = |t: f64| -> [(usize, f64); 2] {
            let x = (t / t_step).clamp(0.0, (Self::N_THETA - 1) as f64);
            let i = (x.floor() as usize).min(Self::N_THETA - 2);
            let w = x - i as f64;
            [(i, 1.0 - w), (i + 1, w)]
        };
        let phi = |p: f64| -> [(usize, f64); 2] {
            let x = p.rem_euclid(2.0 * PI) / p_step;
            let i = (x.floor() as usize).min(Self::N_PHI - 1);
            let w = (x - i as f64).clamp(0.0, 1.0);
            [(i, 1.0 - w), ((i + 1) % Self::N_PHI, w)]
        };
        let (a, b, c, d) = (theta(theta_i), phi(phi_i), theta(theta_v), phi(phi_v));
        let mut v = [0.0; 3];
        for (ia, wa) in a {
            for (ib, wb) in b {
                for (ic, wc) in c {
                    for (id, wd) in d {
                        let w = wa * wb * wc * wd;
                        if w == 0.0 {
                            continue;
                        }
                        if let Some(rgb) = self.cell(Self::index(ia, ib, ic, id)) {
                            for k in 0..3 {
                                v[k] += w * rgb[k];
                            }
                        }
                    }
                }
            }
        }
        v
    }

    /// Number of cells with no negative channel.
    pub fn valid_cells(&self) -> usize {
        (0..Self::CELLS).filter(|&i| self.cell(i).is_some()).count()
    }

    /// Every valid cell as a sample, with
    /// `Angles::from_directions(wi, wv)` for the illumination and view
    /// directions and the stored RGB; missing cells count in `missing`.
    /// All nodes are above the horizon (θ ≤ 75°). `isotropic` is false.
    /// Samples are in cell order.
    pub fn samples(&self, source: &str) -> MeasuredSamples {
        let samples: Vec<MeasuredSample> =
            (0..Self::CELLS).filter_map(|i| self.sample_at(i)).collect();
        let missing = Self::CELLS - samples.len();
        MeasuredSamples {
            source: source.to_string(),
            isotropic: false,
            samples,
            missing,
        }
    }

    /// The samples of [`UtiaTable::samples`], the same values in the same
    /// order, in consecutive pieces of `chunk` (the last may be shorter):
    /// `f` of each piece, in piece order, made and consumed in parallel
    /// (rayon's current pool) one at a time per worker, so the samples are
    /// never all held; the same result for any thread count.
    ///
    /// # Panics
    /// If `chunk` is 0.
    pub fn map_sample_chunks<R: Send>(
        &self,
        chunk: usize,
        f: impl Fn(&[MeasuredSample]) -> R + Sync,
    ) -> Vec<R> {
        use rayon::prelude::*;
        assert!(chunk > 0, "pieces of at least one sample");
        // The valid cells' indices (below 2^18), in cell order.
        let valid: Vec<u32> = (0..Self::CELLS as u32)
            .filter(|&i| self.cell(i as usize).is_some())
            .collect();
        valid
            .par_chunks(chunk)
            .map_init(
                || Vec::with_capacity(chunk),
                |piece: &mut Vec<MeasuredSample>, cells| {
                    piece.clear();
                    piece.extend(cells.iter().filter_map(|&i| self.sample_at(i as usize)));
                    f(piece)
                },
            )
            .collect()
    }

    /// The sample of cell `index` ([`UtiaTable::samples`]), `None` if missing.
    #[inline]
    fn sample_at(&self, index: usize) -> Option<MeasuredSample> {
        let rgb = self.cell(index)?;
        let row = Self::N_THETA * Self::N_PHI;
        let (i_ti, i_pi) = ((index / row) / Self::N_PHI, (index / row) % Self::N_PHI);
        let (i_tv, i_pv) = ((index % row) / Self::N_PHI, index % Self::N_PHI);
        let (ti, pi, tv, pv) = Self::node_angles(i_ti, i_pi, i_tv, i_pv);
        Some(MeasuredSample {
            angles: Angles::from_directions(spherical(ti, pi), spherical(tv, pv)),
            rgb,
        })
    }
}

/// All (i_ti, i_pi, i_tv, i_pv) in file order.
fn grid(n: usize, m: usize) -> impl Iterator<Item = (usize, usize, usize, usize)> {
    (0..n).flat_map(move |a| {
        (0..m).flat_map(move |b| (0..n).flat_map(move |c| (0..m).map(move |d| (a, b, c, d))))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_and_index_agree() {
        assert_eq!(UtiaTable::CELLS, 6 * 48 * 6 * 48);
        assert_eq!(UtiaTable::FILE_BYTES, 248_832 * 8);
        let mut expected = 0;
        for (a, b, c, d) in grid(6, 48) {
            assert_eq!(UtiaTable::index(a, b, c, d), expected);
            expected += 1;
        }
        assert_eq!(expected, UtiaTable::CELLS);
        let (ti, pi, tv, pv) = UtiaTable::node_angles(5, 47, 1, 1);
        assert!((ti.to_degrees() - 75.0).abs() < 1e-12);
        assert!((pi.to_degrees() - 352.5).abs() < 1e-12);
        assert!((tv.to_degrees() - 15.0).abs() < 1e-12);
        assert!((pv.to_degrees() - 7.5).abs() < 1e-12);
    }

    fn synthetic(ti: f64, pi: f64, tv: f64, pv: f64) -> Option<[f64; 3]> {
        if tv > 1.2 && pv > 6.1 {
            return None;
        }
        Some([0.1 + ti + pi, 0.2 + tv + 0.01 * pv, 0.3 + ti * pv])
    }

    #[test]
    fn round_trip_and_values() {
        let dir = tempfile::tempdir().unwrap();
        let t = UtiaTable::from_fn(synthetic);
        let p = dir.path().join("m.bin");
        t.write(&p, false).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(bytes.len() as u64, UtiaTable::FILE_BYTES);
        assert_eq!(bytes, t.to_bytes());
        let back = UtiaTable::read(&p).unwrap();
        assert_eq!(back, t);
        assert_eq!(back.to_bytes(), bytes);

        let idx = UtiaTable::index(2, 10, 3, 20);
        let (ti, pi, tv, pv) = UtiaTable::node_angles(2, 10, 3, 20);
        assert_eq!(back.cell(idx), synthetic(ti, pi, tv, pv));
        // In the file, red of that cell is at byte 8 * idx.
        let red = f64::from_le_bytes(bytes[8 * idx..8 * idx + 8].try_into().unwrap());
        assert_eq!(red, synthetic(ti, pi, tv, pv).unwrap()[0]);

        let e = t.write(&p, false).unwrap_err();
        assert!(matches!(e, LoadError::Exists { .. }), "{e:?}");
    }

    #[test]
    fn sample_pieces_are_the_samples_in_order_for_any_thread_count() {
        let mut raw = UtiaTable::from_fn(synthetic).raw().to_vec();
        raw[UtiaTable::index(0, 0, 0, 0)] = -1.0; // the first cell missing too
        let t = UtiaTable::from_raw(raw);
        let all = t.samples("t").samples;
        assert!(all.len() < UtiaTable::CELLS - 6 * 48);
        crate::samples::assert_pieces_are(&all, &[1000, 8192, 2 * UtiaTable::CELLS], |chunk| {
            t.map_sample_chunks(chunk, |p| p.to_vec())
        });
    }

    #[test]
    fn samples_skip_missing_and_carry_directions() {
        let mut raw = UtiaTable::from_fn(synthetic).raw().to_vec();
        let neg = UtiaTable::index(1, 2, 3, 4);
        raw[2 * UtiaTable::CELLS + neg] = -0.25;
        let t = UtiaTable::from_raw(raw);
        assert_eq!(t.raw()[2 * UtiaTable::CELLS + neg], -0.25);
        assert_eq!(t.cell(neg), None);

        let s = t.samples("m.bin");
        assert!(!s.isotropic);
        assert_eq!(s.source, "m.bin");
        assert_eq!(s.samples.len() + s.missing, UtiaTable::CELLS);
        assert_eq!(s.samples.len(), t.valid_cells());
        // tv = 75° (> 1.2 rad) with pv = 352.5° (> 6.1 rad): 6 * 48 * 1 * 1 cells, plus `neg`.
        assert_eq!(s.missing, 6 * 48 + 1);
        for m in &s.samples {
            let a = m.angles;
            assert!(a.theta_i <= 75f64.to_radians() + 1e-12);
            assert!(a.theta_o <= 75f64.to_radians() + 1e-12);
        }
        // The first sample is cell 0: both directions at the pole.
        let first = s.samples[0];
        assert!(first.angles.theta_i.abs() < 1e-12 && first.angles.theta_o.abs() < 1e-12);
        assert_eq!(Some(first.rgb), t.cell(0));
        // A generic cell: the directions come back from the angles.
        let idx = UtiaTable::index(3, 5, 2, 30);
        let (ti, pi, tv, pv) = UtiaTable::node_angles(3, 5, 2, 30);
        let m = s.samples[(0..idx).filter(|&i| t.cell(i).is_some()).count()];
        assert_eq!(Some(m.rgb), t.cell(idx));
        let close = |a: f64, b: f64| {
            let d = (a - b).rem_euclid(2.0 * PI);
            d.min(2.0 * PI - d) < 1e-9
        };
        assert!((m.angles.theta_i - ti).abs() < 1e-9 && close(m.angles.phi_i, pi));
        assert!((m.angles.theta_o - tv).abs() < 1e-9 && close(m.angles.phi_o, pv));
    }

    #[test]
    fn interpolation_hits_nodes_and_wraps() {
        let t = UtiaTable::from_fn(synthetic);
        let (ti, pi, tv, pv) = UtiaTable::node_angles(2, 10, 3, 20);
        let v = t.interpolate(ti, pi, tv, pv);
        let c = t.cell(UtiaTable::index(2, 10, 3, 20)).unwrap();
        for k in 0..3 {
            assert!((v[k] - c[k]).abs() < 1e-12);
        }
        // Half-way between phi nodes 47 and 0 (wrap) is their mean.
        let (ti, _, tv, pv) = UtiaTable::node_angles(1, 0, 2, 5);
        let half = (352.5f64 + 3.75).to_radians();
        let v = t.interpolate(ti, half, tv, pv);
        let a = t.cell(UtiaTable::index(1, 47, 2, 5)).unwrap();
        let b = t.cell(UtiaTable::index(1, 0, 2, 5)).unwrap();
        for k in 0..3 {
            assert!((v[k] - 0.5 * (a[k] + b[k])).abs() < 1e-12);
        }
    }

    #[test]
    fn malformed_files() {
        let good = UtiaTable::from_fn(|_, _, _, _| Some([1.0; 3])).to_bytes();
        let p = Path::new("dir/m001.bin");
        for bytes in [&[][..], &good[..7], &good[..good.len() - 1]] {
            let e = UtiaTable::from_bytes(bytes, p).unwrap_err();
            assert!(matches!(e, LoadError::WrongSize { .. }), "{e:?}");
            assert!(e.to_string().contains("m001.bin"), "{e}");
        }
        let mut long = good.clone();
        long.push(0);
        let e = UtiaTable::from_bytes(&long, p).unwrap_err();
        assert!(e.to_string().contains("too long"), "{e}");

        let mut bad = good.clone();
        let at = 8 * (UtiaTable::CELLS + 77);
        bad[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let e = UtiaTable::from_bytes(&bad, p).unwrap_err();
        assert!(
            matches!(
                e,
                LoadError::NonFinite {
                    channel: 1,
                    cell: 77,
                    ..
                }
            ),
            "{e:?}"
        );
        bad[at..at + 8].copy_from_slice(&f64::NEG_INFINITY.to_le_bytes());
        let e = UtiaTable::from_bytes(&bad, p).unwrap_err();
        assert!(matches!(e, LoadError::NonFinite { .. }), "{e:?}");

        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("short.bin");
        std::fs::write(&q, &good[..100]).unwrap();
        let e = UtiaTable::read(&q).unwrap_err();
        assert!(
            matches!(e, LoadError::WrongSize { actual: 100, .. }),
            "{e:?}"
        );
    }
}

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
            UtiaTable::from_fn(|ti, _, tv, _| (ti < 1.2).then_some([ti + 0.1, tv + 0.2, 0.3]))
                .to_bytes()
        })
    }

    proptest! {
        // A case copies and parses 2 MB: some cases, many mutations each.
        #![proptest_config(ProptestConfig::with_cases(48))]
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
            match UtiaTable::from_bytes(&b, Path::new("p.binary")) {
                Ok(t) => prop_assert_eq!(t.to_bytes(), b),
                Err(e) => prop_assert!(e.to_string().starts_with("p.binary: "), "{}", e),
            }
        }
    }
}
