//! The BRDF an RGL `.bsdf` file holds, evaluated as Mitsuba 3's `measured`
//! plugin evaluates it (`../shared/docs/RGL_FORMAT.md` section 4): the
//! half vector's point u_m on the `vndf` warp's square, inverted to the
//! sample square ([`crate::rgl_warp`]), `rgb` (or `spectra`) read there
//! bilinearly, times `ndf(u_m) / (4 sigma(u_wi))` when `jacobian` is 1;
//! every table conditioned on (phi_i, theta_i) blends its neighbouring
//! slices linearly. The value is f cos(theta_o); [`RglBrdf::value`] divides
//! the cosine out, as pbrt-v4 does.
//!
//! Directions follow the format: `wi` is the conditioning direction (the
//! view, Mitsuba's `si.wi`), `wo` the other one, both in the local frame
//! (z the normal).
//!
//! The reader checks every field before it builds anything: presence,
//! dtype (float32), rank and extents against each other (Mitsuba's shape
//! rules), finite values, non-negative tables where the warp or the
//! jacobian divide by them, increasing parameter nodes, and sizes within
//! [`MAX_TABLE_VALUES`]; each error names the file and the field.

use std::path::Path;

use crate::error::LoadError;
use crate::geometry::{directions_from_half_diff, spherical, Vec3};
use crate::merl::MerlTable;
use crate::rgl::{Field, TensorFile};
use crate::rgl_warp::{blend, Bilinear, ParamAxis, Warp2D, WarpError};
use crate::utia::UtiaTable;

/// Largest number of values any one table may hold (the database's
/// largest tables hold a few million).
pub const MAX_TABLE_VALUES: usize = 1 << 28;

/// An RGL `.bsdf` file's BRDF, ready to evaluate.
#[derive(Clone, Debug)]
pub struct RglBrdf {
    /// The file's name, for messages.
    pub source: String,
    /// The conditioning parameters' nodes: phi_i, theta_i.
    params: [ParamAxis; 2],
    ndf: Bilinear,
    sigma: Bilinear,
    vndf: Warp2D,
    /// `rgb` or `spectra`: P x T x C slices of N x N.
    data: Bilinear,
    channels: usize,
    /// nm, for spectral files.
    wavelengths: Option<Vec<f64>>,
    /// Linear sRGB from the channels: `to_rgb[c]` is channel c's weight
    /// per RGB component (the identity for RGB files).
    to_rgb: Vec<[f64; 3]>,
    jacobian: bool,
}

fn field<'a>(file: &'a TensorFile, path: &Path, name: &str) -> Result<&'a Field, LoadError> {
    file.get(name)
        .ok_or_else(|| LoadError::invalid(path, format!("field {name:?} is missing")))
}

/// A float32 field's values as f64, its shape checked to have `rank`
/// axes of at least `least` each (the first `free` axes at least 1), every
/// value finite and, with `non_negative`, not below 0.
fn floats(
    f: &Field,
    path: &Path,
    (rank, free, least): (usize, usize, usize),
    non_negative: bool,
) -> Result<Vec<f64>, LoadError> {
    let bad = |p: String| LoadError::invalid(path, format!("field {:?}: {p}", f.name));
    let Some(v) = f.as_f32() else {
        return Err(bad(format!("dtype {:?}, expected float32", f.data.dtype())));
    };
    if f.shape.len() != rank {
        return Err(bad(format!(
            "rank {} (shape {:?}), expected {rank}",
            f.shape.len(),
            f.shape
        )));
    }
    for (a, &n) in f.shape.iter().enumerate() {
        let want = if a < free { 1 } else { least };
        if n < want {
            return Err(bad(format!(
                "axis {a} has {n} entries (shape {:?}), at least {want} needed",
                f.shape
            )));
        }
    }
    if v.len() > MAX_TABLE_VALUES {
        return Err(bad(format!(
            "{} values, more than {MAX_TABLE_VALUES}",
            v.len()
        )));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(bad(format!("value {i} is {}", v[i])));
    }
    if non_negative {
        if let Some(i) = v.iter().position(|&x| x < 0.0) {
            return Err(bad(format!("value {i} is negative ({})", v[i])));
        }
    }
    Ok(v.iter().map(|&x| x as f64).collect())
}

fn increasing(v: &[f64], name: &str, path: &Path) -> Result<(), LoadError> {
    if let Some(k) = v.windows(2).position(|w| w[1] <= w[0]) {
        return Err(LoadError::invalid(
            path,
            format!(
                "field {name:?}: nodes not increasing (entries {k} and {})",
                k + 1
            ),
        ));
    }
    Ok(())
}

impl RglBrdf {
    /// Reads and checks `path`.
    pub fn read(path: &Path) -> Result<Self, LoadError> {
        let file = TensorFile::read(path)?;
        Self::from_file(&file, path)
    }

    /// Checks `file`'s fields (named by `path` in messages) and builds the
    /// BRDF.
    pub fn from_file(file: &TensorFile, path: &Path) -> Result<Self, LoadError> {
        file.validate(path)?;
        let bad = |p: String| LoadError::invalid(path, p);
        let phi = floats(field(file, path, "phi_i")?, path, (1, 1, 1), false)?;
        let theta = floats(field(file, path, "theta_i")?, path, (1, 1, 1), false)?;
        increasing(&phi, "phi_i", path)?;
        increasing(&theta, "theta_i", path)?;
        if theta[0] < 0.0 || theta[theta.len() - 1] > std::f64::consts::FRAC_PI_2 {
            return Err(bad("field \"theta_i\": nodes outside [0, pi/2]".into()));
        }
        let (p, t) = (phi.len(), theta.len());
        let two_d = |name: &str| -> Result<Bilinear, LoadError> {
            let f = field(file, path, name)?;
            let v = floats(f, path, (2, 0, 2), true)?;
            Ok(Bilinear {
                h: f.shape[0],
                w: f.shape[1],
                v,
            })
        };
        let ndf = two_d("ndf")?;
        let sigma = two_d("sigma")?;
        // A conditioned table's first two axes are the parameter nodes.
        let slices = |f: &Field| -> Result<(), LoadError> {
            if f.shape[0] != p || f.shape[1] != t {
                return Err(bad(format!(
                    "field {:?}: shape {:?} does not begin with (len(phi_i), len(theta_i)) = ({p}, {t})",
                    f.name, f.shape
                )));
            }
            Ok(())
        };
        let vf = field(file, path, "vndf")?;
        let vndf_values = floats(vf, path, (4, 2, 2), true)?;
        slices(vf)?;
        let vndf = Warp2D::new(&vndf_values, vf.shape[2], vf.shape[3]).map_err(|e| match e {
            WarpError::Shape => bad("field \"vndf\": slices of fewer than 2 x 2".into()),
            WarpError::Integral { slice } => bad(format!(
                "field \"vndf\": slice {slice} (phi_i node {}, theta_i node {}) integrates to zero",
                slice / t,
                slice % t
            )),
        })?;
        let lf = field(file, path, "luminance")?;
        floats(lf, path, (4, 2, 2), true)?;
        slices(lf)?;
        let (wavelengths, df) = match file.get("wavelengths") {
            Some(wf) => {
                let w = floats(wf, path, (1, 1, 1), true)?;
                increasing(&w, "wavelengths", path)?;
                (Some(w), field(file, path, "spectra")?)
            }
            None => (None, field(file, path, "rgb")?),
        };
        let data_values = floats(df, path, (5, 3, 2), false)?;
        slices(df)?;
        let channels = df.shape[2];
        let want_channels = wavelengths.as_ref().map_or(3, Vec::len);
        if channels != want_channels {
            return Err(bad(format!(
                "field {:?}: {channels} channels (shape {:?}), expected {want_channels}",
                df.name, df.shape
            )));
        }
        if df.shape[3..] != lf.shape[2..] || df.shape[3] != df.shape[4] {
            return Err(bad(format!(
                "field {:?}: sample grid {:?} is not square or not luminance's {:?}",
                df.name,
                &df.shape[3..],
                &lf.shape[2..]
            )));
        }
        let jf = field(file, path, "jacobian")?;
        let jacobian = match jf.as_u8() {
            Some([j]) => *j != 0,
            _ => {
                return Err(bad(format!(
                    "field \"jacobian\": expected one uint8 value, got {:?} of {:?}",
                    jf.shape,
                    jf.data.dtype()
                )))
            }
        };
        let to_rgb = match &wavelengths {
            Some(w) => crate::spectrum::spectral_to_rgb(w),
            None => vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        };
        Ok(RglBrdf {
            source: path.display().to_string(),
            to_rgb,
            params: [ParamAxis(phi), ParamAxis(theta)],
            ndf,
            sigma,
            vndf,
            data: Bilinear {
                h: df.shape[3],
                w: df.shape[4],
                v: data_values,
            },
            channels,
            wavelengths,
            jacobian,
        })
    }

    /// Whether the file is isotropic (at most two `phi_i` nodes).
    pub fn is_isotropic(&self) -> bool {
        self.params[0].0.len() <= 2
    }

    /// The file's last `theta_i` node (radians): how far from the normal
    /// it conditions on a measured direction.
    pub fn max_theta_i(&self) -> f64 {
        self.params[1].0[self.params[1].0.len() - 1]
    }

    /// Channels of the value: 3 for RGB files, one per wavelength for
    /// spectral ones.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The wavelengths (nm) of a spectral file.
    pub fn wavelengths(&self) -> Option<&[f64]> {
        self.wavelengths.as_deref()
    }

    /// f cos(theta_o) per channel at (wi, wo), what Mitsuba's `eval`
    /// returns (wi the conditioning direction); zero when either is at or
    /// below the horizon. `out` holds [`Self::channels`] values.
    pub fn value_cos(&self, wi: Vec3, wo: Vec3, out: &mut [f64]) {
        out.iter_mut().for_each(|v| *v = 0.0);
        if !(wi[2] > 0.0 && wo[2] > 0.0) {
            return;
        }
        let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        if n <= 0.0 || !n.is_finite() {
            return;
        }
        let m = [h[0] / n, h[1] / n, h[2] / n];
        let theta = |v: Vec3| v[2].clamp(-1.0, 1.0).acos();
        let u_theta = |t: f64| (t / std::f64::consts::FRAC_PI_2).max(0.0).sqrt();
        let u_phi = |p: f64| (p + std::f64::consts::PI) / (2.0 * std::f64::consts::PI);
        let (theta_i, phi_i) = (theta(wi), wi[1].atan2(wi[0]));
        let phi_m = m[1].atan2(m[0]);
        let phi_m = if self.is_isotropic() {
            phi_m - phi_i
        } else {
            phi_m
        };
        let mut u_m = [u_theta(theta(m)), u_phi(phi_m)];
        u_m[1] -= u_m[1].floor();
        let u_wi = [u_theta(theta_i), u_phi(phi_i)];
        let b = blend(&self.params, &[phi_i, theta_i]);
        let (s, _) = self.vndf.invert(u_m, &b);
        let scale = if self.jacobian {
            let d = self.ndf.at(u_m[0], u_m[1], &[(0, 1.0)]);
            let sg = self.sigma.at(u_wi[0], u_wi[1], &[(0, 1.0)]);
            if sg > 0.0 {
                d / (4.0 * sg)
            } else {
                0.0
            }
        } else {
            1.0
        };
        // The data's slices are (phi_i, theta_i, channel): one blend buffer
        // for every channel.
        let mut bc = b.clone();
        for (c, o) in out.iter_mut().enumerate() {
            for (slot, &(k, w)) in bc.iter_mut().zip(&b) {
                *slot = (k * self.channels + c, w);
            }
            *o = self.data.at(s[0], s[1], &bc) * scale;
        }
    }

    /// The BRDF f per channel at (wi, wo): [`Self::value_cos`] over
    /// cos(theta_o), negative values clamped to 0 (as pbrt-v4 does).
    pub fn value(&self, wi: Vec3, wo: Vec3, out: &mut [f64]) {
        self.value_cos(wi, wo, out);
        for v in out.iter_mut() {
            let f = *v / wo[2];
            *v = if wo[2] > 0.0 && f.is_finite() {
                f.max(0.0)
            } else {
                0.0
            };
        }
    }

    /// The file's BRDF as a MERL table: [`Self::rgb`] at every cell's node
    /// with the view (MERL's wo) as the file's conditioning direction.
    /// Cells with a direction beyond the file's last `theta_i` node are
    /// missing: the file holds nothing measured there, and near the
    /// horizon its f cos(theta_o), divided by a vanishing cosine, would
    /// give values without bound (up to 1e13 measured on an export).
    /// Only for isotropic files (a MERL table has no azimuth of its own:
    /// see [`Self::to_utia`] for anisotropic ones).
    pub fn to_merl(&self) -> Result<MerlTable, LoadError> {
        if !self.is_isotropic() {
            return Err(LoadError::invalid(
                Path::new(&self.source),
                format!(
                    "an anisotropic .bsdf file ({} phi_i nodes) cannot be read as an isotropic MERL table; read it as a UTIA table",
                    self.params[0].0.len()
                ),
            ));
        }
        let lowest_cos = self.max_theta_i().cos();
        Ok(MerlTable::from_fn(|th, td, pd| {
            let (wi, wo) = directions_from_half_diff(th, 0.0, td, pd);
            self.within(wi, wo, lowest_cos).then(|| self.rgb(wo, wi))
        }))
    }

    /// The file's BRDF as a UTIA table (its 6 x 48 x 6 x 48 nodes, azimuths
    /// absolute, as the file's `phi_i`): [`Self::rgb`] with the view as the
    /// conditioning direction; cells beyond the last `theta_i` node are
    /// missing, as in [`Self::to_merl`]. For files of either kind (an
    /// isotropic file's value depends on the azimuth difference only).
    pub fn to_utia(&self) -> UtiaTable {
        let lowest_cos = self.max_theta_i().cos();
        UtiaTable::from_fn(|ti, pi, tv, pv| {
            let (wi, wo) = (spherical(ti, pi), spherical(tv, pv));
            self.within(wi, wo, lowest_cos).then(|| self.rgb(wo, wi))
        })
    }

    /// Whether both directions are above the horizon and within the file's
    /// last `theta_i` node (`lowest_cos` its cosine).
    fn within(&self, wi: Vec3, wo: Vec3, lowest_cos: f64) -> bool {
        wi[2] >= lowest_cos && wo[2] >= lowest_cos && wi[2] > 0.0 && wo[2] > 0.0
    }

    /// The BRDF f of a spectral file at (wi, wo) and each of `lambdas`
    /// (nm), as Mitsuba 3's spectral variants evaluate it: linear between
    /// the file's wavelength nodes, the end nodes' values outside them.
    /// `None` for an RGB file. (Blending the slices before the jacobian, as
    /// Mitsuba does, or the values after it is the same: both are linear.)
    pub fn spectral_value(&self, wi: Vec3, wo: Vec3, lambdas: &[f64]) -> Option<Vec<f64>> {
        let nodes = self.wavelengths.as_deref()?;
        let mut v = vec![0.0; self.channels];
        self.value(wi, wo, &mut v);
        Some(
            lambdas
                .iter()
                .map(|&l| {
                    let k = nodes.partition_point(|&n| n <= l);
                    if k == 0 {
                        v[0]
                    } else if k == nodes.len() {
                        v[k - 1]
                    } else {
                        let t = (l - nodes[k - 1]) / (nodes[k] - nodes[k - 1]);
                        v[k - 1] * (1.0 - t) + v[k] * t
                    }
                })
                .collect(),
        )
    }

    /// The BRDF f in linear sRGB at (wi, wo) ([`Self::value`], spectral
    /// files by [`crate::spectrum`]'s route), never negative.
    pub fn rgb(&self, wi: Vec3, wo: Vec3) -> [f64; 3] {
        let mut v = [0.0; 64];
        let mut heap;
        let v = if self.channels <= v.len() {
            &mut v[..self.channels]
        } else {
            heap = vec![0.0; self.channels];
            &mut heap[..]
        };
        self.value(wi, wo, v);
        let mut rgb = [0.0; 3];
        for (c, x) in v.iter().enumerate() {
            for (a, o) in rgb.iter_mut().enumerate() {
                *o += self.to_rgb[c][a] * x;
            }
        }
        // A file of extreme values (a sigma near 0, say) must not give an
        // infinite or NaN value: such a value is no measurement.
        rgb.map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A valid isotropic RGB file: identity warp (constant vndf), ndf 1 and
    /// sigma 1/4 (jacobian 1), rgb[c] = (c + 1) / 10 everywhere, so that
    /// f cos(theta_o) = (c + 1) / 10.
    fn file(thetas: usize, n: usize) -> TensorFile {
        let t: Vec<f32> = (0..thetas).map(|k| k as f32 * 0.4).collect();
        let rgb: Vec<f32> = (0..thetas)
            .flat_map(|_| {
                (0..3).flat_map(move |c| std::iter::repeat((c + 1) as f32 / 10.0).take(n * n))
            })
            .collect();
        TensorFile {
            fields: vec![
                Field::f32("phi_i", &[1], vec![0.0]),
                Field::f32("theta_i", &[thetas], t),
                Field::f32("ndf", &[2, 2], vec![1.0; 4]),
                Field::f32("sigma", &[2, 3], vec![0.25; 6]),
                Field::f32("vndf", &[1, thetas, 2, 2], vec![1.0; thetas * 4]),
                Field::f32("luminance", &[1, thetas, n, n], vec![1.0; thetas * n * n]),
                Field::f32("rgb", &[1, thetas, 3, n, n], rgb),
                Field::u8("jacobian", &[1], vec![1]),
            ],
        }
    }

    fn refused(f: &TensorFile) -> String {
        let e = RglBrdf::from_file(f, Path::new("x.bsdf"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.bsdf"), "{e}");
        e
    }

    fn with(mut f: TensorFile, name: &str, change: impl FnOnce(&mut Field)) -> TensorFile {
        change(f.fields.iter_mut().find(|g| g.name == name).unwrap());
        f
    }

    #[test]
    fn a_constant_file_reads_its_value_over_the_cosine() {
        let b = RglBrdf::from_file(&file(3, 4), Path::new("x.bsdf")).unwrap();
        assert!(b.is_isotropic() && b.channels() == 3 && b.wavelengths().is_none());
        let mut v = [0.0; 3];
        for (ti, to, dp) in [(0.1, 0.7, 2.0), (0.5, 0.2, -1.0), (0.79, 1.2, 3.0)] {
            let (wi, wo) = (spherical(ti, 0.3), spherical(to, 0.3 + dp));
            b.value(wi, wo, &mut v);
            for c in 0..3 {
                let want = (c + 1) as f64 / 10.0 / wo[2];
                assert!((v[c] - want).abs() < 1e-6 * want, "{v:?}");
            }
        }
        b.value(spherical(0.3, 0.0), [0.0, 0.6, -0.8], &mut v);
        assert_eq!(v, [0.0; 3]);
    }

    #[test]
    fn spectral_values_are_linear_between_wavelength_nodes_and_clamped_outside() {
        // The constant file's three channels as spectra at 400, 500, 600 nm.
        let mut f = file(3, 4);
        for g in f.fields.iter_mut().filter(|g| g.name == "rgb") {
            g.name = "spectra".into();
        }
        f.fields
            .push(Field::f32("wavelengths", &[3], vec![400.0, 500.0, 600.0]));
        let b = RglBrdf::from_file(&f, Path::new("x.bsdf")).unwrap();
        let (wi, wo) = (spherical(0.2, 0.0), spherical(0.6, 2.0));
        let v = b
            .spectral_value(wi, wo, &[300.0, 400.0, 450.0, 575.0, 600.0, 900.0])
            .unwrap();
        let want = [0.1, 0.1, 0.15, 0.275, 0.3, 0.3].map(|x| x / wo[2]);
        for (a, w) in v.iter().zip(want) {
            assert!((a - w).abs() < 1e-6 * w, "{v:?} against {want:?}");
        }
        let rgb = RglBrdf::from_file(&file(3, 4), Path::new("x.bsdf")).unwrap();
        assert!(rgb.spectral_value(wi, wo, &[500.0]).is_none());
    }

    #[test]
    fn hostile_files_are_refused_naming_the_field() {
        let e = refused(&TensorFile {
            fields: file(2, 2)
                .fields
                .into_iter()
                .filter(|f| f.name != "vndf")
                .collect(),
        });
        assert!(e.contains("\"vndf\" is missing"), "{e}");
        let e = refused(&with(file(2, 2), "ndf", |f| {
            f.data = crate::rgl::Data::F32(vec![1.0, f32::NAN, 1.0, 1.0])
        }));
        assert!(e.contains("\"ndf\"") && e.contains("NaN"), "{e}");
        let e = refused(&with(file(2, 2), "vndf", |f| f.shape = vec![1, 1, 2, 4]));
        assert!(e.contains("\"vndf\"") && e.contains("len(theta_i)"), "{e}");
        let e = refused(&with(file(2, 2), "vndf", |f| {
            f.data = crate::rgl::Data::F32(vec![1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
        }));
        assert!(
            e.contains("slice 1") && e.contains("integrates to zero"),
            "{e}"
        );
        let e = refused(&with(file(2, 2), "sigma", |f| {
            f.data = crate::rgl::Data::F32(vec![0.25, -1.0, 0.25, 0.25, 0.25, 0.25])
        }));
        assert!(e.contains("\"sigma\"") && e.contains("negative"), "{e}");
        let e = refused(&with(file(2, 2), "theta_i", |f| {
            f.data = crate::rgl::Data::F32(vec![0.5, 0.5])
        }));
        assert!(
            e.contains("\"theta_i\"") && e.contains("not increasing"),
            "{e}"
        );
        let e = refused(&with(file(2, 2), "rgb", |f| f.shape = vec![1, 2, 4, 2, 1]));
        assert!(e.contains("\"rgb\""), "{e}");
        let e = refused(&with(file(2, 2), "jacobian", |f| {
            *f = Field::f32("jacobian", &[1], vec![1.0])
        }));
        assert!(e.contains("\"jacobian\""), "{e}");
        let e = refused(&with(file(2, 2), "luminance", |f| {
            *f = Field::u8("luminance", &[1, 2, 2, 2], vec![1; 8])
        }));
        assert!(e.contains("\"luminance\"") && e.contains("float32"), "{e}");
        let e = refused(&with(file(2, 2), "ndf", |f| f.shape = vec![4]));
        assert!(e.contains("\"ndf\"") && e.contains("rank"), "{e}");
    }

    #[test]
    fn a_spectral_file_needs_its_spectra() {
        let mut f = file(2, 2);
        f.fields
            .push(Field::f32("wavelengths", &[3], vec![450.0, 550.0, 650.0]));
        let e = refused(&f);
        assert!(e.contains("\"spectra\" is missing"), "{e}");
        for g in f.fields.iter_mut().filter(|g| g.name == "rgb") {
            g.name = "spectra".into();
        }
        let b = RglBrdf::from_file(&f, Path::new("x.bsdf")).unwrap();
        assert_eq!(b.wavelengths(), Some(&[450.0, 550.0, 650.0][..]));
    }
}
