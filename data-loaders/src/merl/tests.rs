//! Unit tests of the MERL reader, writer and sample views.

use super::*;
use crate::geometry::directions_from_half_diff;

#[test]
fn constants_agree() {
    assert_eq!(
        MerlTable::CELLS,
        MerlTable::RES_THETA_H * MerlTable::RES_THETA_D * MerlTable::RES_PHI_D
    );
    assert_eq!(
        MerlTable::FILE_BYTES,
        (HEADER_BYTES + 3 * MerlTable::CELLS * 8) as u64
    );
    assert_eq!(MerlTable::index(89, 89, 179), MerlTable::CELLS - 1);
    assert_eq!(MerlTable::index(0, 1, 0), 180);
    assert_eq!(MerlTable::index(1, 0, 0), 180 * 90);
}

/// `lookup_interpolated` returns a node's own value at the node, is
/// exact for values linear in the index coordinates (sqrt(theta_h),
/// theta_d, and phi_d away from the wrap), wraps phi_d with period pi,
/// holds the last theta node, and leaves missing corners out.
#[test]
fn interpolated_lookup_is_exact_at_nodes_and_for_linear_values() {
    let idx = |th: f64, td: f64, pd: f64| {
        (
            (th / FRAC_PI_2).sqrt() * 90.0,
            td / FRAC_PI_2 * 90.0,
            pd / PI * 180.0,
        )
    };
    let linear = MerlTable::from_fn(|th, td, pd| {
        let (a, b, c) = idx(th, td, pd);
        Some([1.0 + a, 2.0 + 0.5 * b, 3.0 + 0.25 * c])
    });
    let close =
        |x: [f64; 3], y: [f64; 3]| (0..3).all(|k| (x[k] - y[k]).abs() < 1e-9 * (1.0 + y[k].abs()));
    for (i, j, k) in [(0, 0, 0), (3, 40, 17), (45, 89, 179), (89, 10, 90)] {
        let (th, td, pd) = MerlTable::node_angles(i, j, k);
        let want = linear.cell(MerlTable::index(i, j, k)).unwrap();
        let got = linear.lookup_interpolated(th, td, pd).unwrap();
        assert!(close(got, want), "node {i} {j} {k}: {got:?} {want:?}");
    }
    // Between nodes (phi_d below the last node, so no wrap).
    for (a, b, c) in [(0.3, 0.5, 0.5), (12.25, 33.5, 100.75), (88.9, 88.1, 178.5)] {
        let th = (a / 90.0f64).powi(2) * FRAC_PI_2;
        let (td, pd) = (b / 90.0 * FRAC_PI_2, c / 180.0 * PI);
        let got = linear.lookup_interpolated(th, td, pd).unwrap();
        assert!(
            close(got, [1.0 + a, 2.0 + 0.5 * b, 3.0 + 0.25 * c]),
            "{a} {b} {c}: {got:?}"
        );
    }
    // phi_d wraps: halfway between node 179 and node 0 (= pi).
    let wrap = linear
        .lookup_interpolated(0.1, 0.2, (179.5 / 180.0) * PI)
        .unwrap();
    assert!((wrap[2] - (3.0 + 0.25 * 89.5)).abs() < 1e-9, "{wrap:?}");
    // Past the last theta nodes: held.
    let far = linear
        .lookup_interpolated(FRAC_PI_2, FRAC_PI_2, 0.0)
        .unwrap();
    assert!(close(far, [1.0 + 89.0, 2.0 + 0.5 * 89.0, 3.0]), "{far:?}");
    // A missing corner is left out: halfway in theta_d towards a missing
    // node gives the valid node's value; all missing gives None.
    let holes = MerlTable::from_fn(|_, td, _| (td < 0.5).then_some([1.0, 2.0, 3.0]));
    let (_, td_last, _) = MerlTable::node_angles(0, 28, 0);
    let (_, td_next, _) = MerlTable::node_angles(0, 29, 0);
    assert!(td_last < 0.5 && td_next >= 0.5);
    let mid = holes
        .lookup_interpolated(0.01, 0.5 * (td_last + td_next), 0.3)
        .unwrap();
    assert_eq!(mid, [1.0, 2.0, 3.0]);
    assert_eq!(holes.lookup_interpolated(0.01, 1.2, 0.3), None);
    assert_eq!(holes.lookup_interpolated(f64::NAN, 0.1, 0.3), None);
}

/// The parallel row build gives, for any thread count, exactly the
/// samples of a plain cell-order pass with `Angles::from_half_diff`.
#[test]
fn samples_match_a_serial_pass_for_any_thread_count() {
    let table = MerlTable::from_fn(|th, td, pd| {
        // Some missing cells, scattered over the rows.
        ((th + 3.0 * td + pd).sin() > -0.8).then_some([th + 0.1, td + 0.2, pd + 0.3])
    });
    let mut expected = Vec::new();
    let mut missing = 0;
    for i_th in 0..MerlTable::RES_THETA_H {
        for i_td in 0..MerlTable::RES_THETA_D {
            for i_pd in 0..MerlTable::RES_PHI_D {
                let (th, td, pd) = MerlTable::node_angles(i_th, i_td, i_pd);
                let (wi, wo) = directions_from_half_diff(th, 0.0, td, pd);
                match table.cell(MerlTable::index(i_th, i_td, i_pd)) {
                    Some(rgb) if wi[2] > 0.0 && wo[2] > 0.0 => expected.push(MeasuredSample {
                        angles: Angles::from_half_diff(th, 0.0, td, pd),
                        rgb,
                    }),
                    _ => missing += 1,
                }
            }
        }
    }
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let got = pool.install(|| table.samples("t"));
        assert_eq!(got.missing, missing);
        assert_eq!(got.samples.len() + got.missing, MerlTable::CELLS);
        assert!(got.samples == expected, "{threads} threads");
    }
}

/// The compact samples are `samples()`, index for index: the same
/// records, elevations, values and rows, for any thread count.
#[test]
fn compact_samples_are_the_samples_for_any_thread_count() {
    let table = MerlTable::from_fn(|th, td, pd| {
        ((th - 2.0 * td + 3.0 * pd).sin() > -0.6).then_some([th + 0.1, td, pd * 2.0])
    });
    let all = table.samples("t");
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let grid = pool.install(|| MerlSamples::new(table.clone(), "t"));
        assert_eq!(grid.len(), all.samples.len());
        assert_eq!(grid.missing(), all.missing);
        let mut next = 0;
        for row in 0..MERL_ROWS {
            let r = grid.row(row);
            assert_eq!(r.start, next);
            next = r.end;
            for i in r {
                let s = &all.samples[i];
                assert_eq!(grid.sample(i), *s);
                assert_eq!(grid.theta(i), [s.angles.theta_i, s.angles.theta_o]);
                assert_eq!(grid.half_diff(i), (s.angles.theta_h, s.angles.theta_d));
                assert_eq!(grid.rgb(i), s.rgb);
                assert_eq!(grid.cell(i) / MerlTable::RES_PHI_D, row);
            }
        }
        assert_eq!(next, grid.len());
    }
}

#[test]
fn sample_pieces_are_the_samples_in_order_for_any_thread_count() {
    let table = MerlTable::from_fn(|th, td, pd| {
        ((2.0 * th + td - pd).cos() > -0.7).then_some([th, td + 0.5, pd + 1.0])
    });
    let all = table.samples("t").samples;
    crate::samples::assert_pieces_are(&all, &[1000, 8192, 20_000, 2 * MerlTable::CELLS], |chunk| {
        table.map_sample_chunks(chunk, |p| p.to_vec())
    });
}

#[test]
fn every_node_bins_to_itself() {
    for i in 0..90 {
        let (th, _, _) = MerlTable::node_angles(i, 0, 0);
        let x = (th / FRAC_PI_2).sqrt() * 90.0;
        assert_eq!(bin(x, 90), i);
    }
    for j in 0..90 {
        let (_, td, _) = MerlTable::node_angles(0, j, 0);
        assert_eq!(bin(td / FRAC_PI_2 * 90.0, 90), j);
    }
    for k in 0..180 {
        let (_, _, pd) = MerlTable::node_angles(0, 0, k);
        assert_eq!(bin(pd / PI * 180.0, 180), k);
    }
}

#[test]
fn bins_truncate_and_clamp() {
    assert_eq!(bin(-3.0, 90), 0);
    assert_eq!(bin(0.999, 90), 0);
    assert_eq!(bin(1.0, 90), 1);
    assert_eq!(bin(89.5, 90), 89);
    assert_eq!(bin(1e300, 90), 89);
    assert_eq!(bin(f64::INFINITY, 90), 89);
    assert_eq!(bin(f64::NEG_INFINITY, 90), 0);
}
