//! The batch interface (`NpfBxdf::eval_batch`, `sample_batch`,
//! `pdf_batch`) gives exactly the per-call values, for models with and
//! without the flat evaluator, and rejects slices of different lengths.

use npf::bsdf::{BsdfError, Directions, NpfBxdf, SampleBatch};
use npf::model::Layout;
use npf::synth::known_factor_model;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// n random directions over the whole sphere (some below the horizon) as
/// structure of arrays.
fn directions(rng: &mut Pcg64, n: usize) -> [Vec<f64>; 3] {
    let mut d = [vec![], vec![], vec![]];
    for _ in 0..n {
        let z: f64 = 2.0 * rng.gen::<f64>() - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let p = rng.gen::<f64>() * std::f64::consts::TAU;
        for (c, v) in [r * p.cos(), r * p.sin(), z].into_iter().enumerate() {
            d[c].push(v);
        }
    }
    d
}

fn dirs(d: &[Vec<f64>; 3]) -> Directions<'_> {
    Directions::new(&d[0], &d[1], &d[2]).unwrap()
}

fn models() -> Vec<(&'static str, NpfBxdf)> {
    let mut six = known_factor_model(Layout::default(), &[0.02, 0.05, 0.1, 0.2, 0.4, 0.8]);
    six.diffuse = [0.1, 0.2, 0.3];
    vec![
        (
            "three lobes",
            known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]),
        ),
        (
            "one lobe",
            known_factor_model(Layout::isotropic(30), &[0.2]),
        ),
        // More lobes than the flat evaluator holds: per-call fallback.
        ("six lobes", six),
        (
            "anisotropic",
            known_factor_model(Layout::anisotropic(), &[0.1, 0.3]),
        ),
    ]
    .into_iter()
    .map(|(name, m)| (name, NpfBxdf::new(m).unwrap()))
    .collect()
}

#[test]
fn batches_equal_the_per_call_values_bit_for_bit() {
    let mut rng = Pcg64::seed_from_u64(13);
    for (name, b) in models() {
        for n in [0, 1, 2, 5, 1027] {
            let (wo, wi) = (directions(&mut rng, n), directions(&mut rng, n));
            let mut f = [vec![f64::NAN; n], vec![f64::NAN; n], vec![f64::NAN; n]];
            let [f0, f1, f2] = &mut f;
            b.eval_batch(dirs(&wo), dirs(&wi), [f0, f1, f2]).unwrap();
            let mut p = vec![f64::NAN; n];
            b.pdf_batch(dirs(&wo), dirs(&wi), &mut p).unwrap();
            let u: [Vec<f64>; 3] = std::array::from_fn(|_| (0..n).map(|_| rng.gen()).collect());
            let mut s = SampleBatch::default();
            b.sample_batch(dirs(&wo), [&u[0], &u[1], &u[2]], &mut s)
                .unwrap();
            assert_eq!(s.len(), n);
            let mut drawn = 0;
            for j in 0..n {
                let (o, i) = (dirs(&wo).get(j), dirs(&wi).get(j));
                let e = b.eval(o, i);
                let got = [f[0][j], f[1][j], f[2][j]];
                assert_eq!(
                    got.map(f64::to_bits),
                    e.map(f64::to_bits),
                    "{name} eval {j}"
                );
                assert_eq!(p[j].to_bits(), b.pdf(o, i).to_bits(), "{name} pdf {j}");
                let one = b.sample(o, u[0][j], [u[1][j], u[2][j]]);
                let got = s.get(j);
                assert_eq!(got.component, one.component, "{name} sample {j}");
                for (x, y) in [
                    (got.wi.as_slice(), one.wi.as_slice()),
                    (&got.f, &one.f),
                    (&got.weight, &one.weight),
                    (&[got.pdf], &[one.pdf]),
                ] {
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(x), bits(y), "{name} sample {j}");
                }
                drawn += usize::from(!one.is_lost());
            }
            // The comparison is not vacuous: most draws carry light.
            if n > 1000 {
                assert!(drawn > n / 3, "{name}: {drawn} of {n} drawn");
            }
        }
    }
}

#[test]
fn slices_of_different_lengths_are_an_error() {
    let b = NpfBxdf::new(known_factor_model(Layout::default(), &[0.1])).unwrap();
    let (a, c) = (vec![0.0; 4], vec![1.0; 3]);
    assert!(matches!(
        Directions::new(&a, &a, &c),
        Err(BsdfError::BatchLength {
            expected: 4,
            found: 3,
            ..
        })
    ));
    let d4 = Directions::new(&a, &a, &a).unwrap();
    let d3 = Directions::new(&c, &c, &c).unwrap();
    let (mut x, mut y, mut z) = (vec![0.0; 4], vec![0.0; 4], vec![0.0; 3]);
    let e = b.eval_batch(d4, d4, [&mut x, &mut y, &mut z]).unwrap_err();
    assert!(e.to_string().contains("eval output"), "{e}");
    let mut w = vec![0.0; 4];
    assert!(b.eval_batch(d4, d3, [&mut x, &mut y, &mut w]).is_err());
    assert!(b.pdf_batch(d4, d4, &mut z).is_err());
    let mut s = SampleBatch::default();
    assert!(b.sample_batch(d4, [&a, &a, &c], &mut s).is_err());
    // A hand-built Directions with unequal slices is caught too.
    let bad = Directions {
        x: &a,
        y: &c,
        z: &a,
    };
    assert!(b.pdf_batch(bad, d4, &mut [0.0; 4]).is_err());
}
