//! Spectra to RGB: the one linear route npf takes from a spectral
//! measurement (an RGL `.bsdf` file's `spectra`) to linear sRGB.
//!
//! The spectrum is the piecewise-linear interpolant of the values over
//! their wavelengths, held constant beyond the ends (as Mitsuba 3
//! interpolates a spectral file), integrated over 360-830 nm against the
//! CIE 1931 colour-matching functions (the multi-lobe fit of Wyman, Sloan
//! and Shirley 2013) into XYZ under an equal-energy light; XYZ is scaled
//! per component so that the constant spectrum 1 lands on D65's white,
//! then taken to linear sRGB (Rec. 709 primaries). So a spectrally flat
//! reflectance is grey with that value in every channel, and the route is
//! linear: one weight per wavelength and RGB component.

/// One lobe of the colour-matching fit: a Gaussian with a different
/// width on each side of its centre.
fn lobe(l: f64, (mu, below, above): (f64, f64, f64)) -> f64 {
    let s = if l < mu { below } else { above };
    (-0.5 * ((l - mu) / s).powi(2)).exp()
}

/// CIE 1931 x-bar, y-bar, z-bar at `l` nm (Wyman, Sloan and Shirley 2013,
/// "Simple Analytic Approximations to the CIE XYZ Color Matching
/// Functions", their multi-lobe fit).
pub fn cie_xyz(l: f64) -> [f64; 3] {
    [
        1.056 * lobe(l, (599.8, 37.9, 31.0)) + 0.362 * lobe(l, (442.0, 16.0, 26.7))
            - 0.065 * lobe(l, (501.1, 20.4, 26.2)),
        0.821 * lobe(l, (568.8, 46.9, 40.5)) + 0.286 * lobe(l, (530.9, 16.3, 31.1)),
        1.217 * lobe(l, (437.0, 11.8, 36.0)) + 0.681 * lobe(l, (459.0, 26.0, 13.8)),
    ]
}

/// linear sRGB from XYZ (IEC 61966-2-1, D65 white).
const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.2404542, -1.5371385, -0.4985314],
    [-0.9692660, 1.8760108, 0.0415560],
    [0.0556434, -0.2040259, 1.0572252],
];

/// D65's white point in XYZ (Y = 1).
const D65_WHITE: [f64; 3] = [0.95047, 1.0, 1.08883];

/// The weights that take a spectral file's channels (at `wavelengths`,
/// nm, increasing) to linear sRGB: the route of this module's
/// documentation, a 1 nm midpoint rule over 360-830 nm.
pub fn spectral_to_rgb(wavelengths: &[f64]) -> Vec<[f64; 3]> {
    let n = wavelengths.len();
    // XYZ per channel, and of the constant spectrum.
    let mut xyz = vec![[0.0; 3]; n];
    let mut flat = [0.0; 3];
    for step in 0..470 {
        let l = 360.5 + step as f64;
        let cmf = cie_xyz(l);
        // The hat functions of the linear interpolant, held at the ends.
        let mut hats = vec![0.0; n];
        if n == 1 || l <= wavelengths[0] {
            hats[0] = 1.0;
        } else if l >= wavelengths[n - 1] {
            hats[n - 1] = 1.0;
        } else {
            let k = wavelengths.partition_point(|&w| w <= l) - 1;
            let t = (l - wavelengths[k]) / (wavelengths[k + 1] - wavelengths[k]);
            hats[k] = 1.0 - t;
            hats[k + 1] = t;
        }
        for (c, h) in hats.iter().enumerate() {
            for a in 0..3 {
                xyz[c][a] += h * cmf[a];
            }
        }
        for a in 0..3 {
            flat[a] += cmf[a];
        }
    }
    xyz.iter()
        .map(|v| {
            let balanced: [f64; 3] = std::array::from_fn(|a| v[a] * D65_WHITE[a] / flat[a]);
            std::array::from_fn(|r| (0..3).map(|a| XYZ_TO_SRGB[r][a] * balanced[a]).sum())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_spectrum_is_white() {
        for w in [
            vec![550.0],
            vec![400.0, 500.0, 600.0, 700.0],
            (0..10).map(|k| 397.0 + 34.0 * k as f64).collect(),
        ] {
            let m = spectral_to_rgb(&w);
            let rgb: [f64; 3] = std::array::from_fn(|a| m.iter().map(|c| c[a]).sum());
            for a in 0..3 {
                assert!((rgb[a] - 1.0).abs() < 1e-3, "{w:?}: {rgb:?}");
            }
        }
    }

    #[test]
    fn the_colour_matching_fit_peaks_where_cie_1931_does() {
        let peak = |a: usize| {
            (360..830)
                .max_by(|&x, &y| cie_xyz(x as f64)[a].total_cmp(&cie_xyz(y as f64)[a]))
                .unwrap()
        };
        assert!((595..=602).contains(&peak(0)), "{}", peak(0));
        assert!((553..=560).contains(&peak(1)), "{}", peak(1));
        assert!((442..=449).contains(&peak(2)), "{}", peak(2));
        // The fit's y-bar is within 2 % of CIE 1931's 1.0 at 555 nm.
        assert!((cie_xyz(555.0)[1] - 1.0).abs() < 0.02);
    }

    #[test]
    fn a_red_spectrum_is_red() {
        let w: Vec<f64> = (0..10).map(|k| 397.0 + 34.0 * k as f64).collect();
        let m = spectral_to_rgb(&w);
        let rgb: [f64; 3] = std::array::from_fn(|a| {
            m.iter()
                .zip(&w)
                .filter(|(_, &l)| l > 620.0)
                .map(|(c, _)| c[a])
                .sum()
        });
        assert!(
            rgb[0] > 0.3 && rgb[1].abs() < 0.2 * rgb[0] && rgb[2].abs() < 0.2 * rgb[0],
            "{rgb:?}"
        );
    }
}
