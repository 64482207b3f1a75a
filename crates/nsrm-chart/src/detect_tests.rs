//! The unit tests of `detect.rs` (moved beside it to keep the file short).

use super::*;
use crate::ChartKind;
use nsrm::Layout;

/// Blobs of area `side²` at the centres of a `cols × rows` grid of pitch `p` from `o`,
/// skipping `(c, r)` in `skip`.
fn grid(o: [f64; 2], p: f64, cols: i32, rows: i32, skip: &[(i32, i32)]) -> Vec<Blob> {
    let mut v = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            if !skip.contains(&(c, r)) {
                v.push(Blob {
                    c: [o[0] + p * c as f64, o[1] + p * r as f64],
                    area: (0.7 * p) * (0.7 * p),
                });
            }
        }
    }
    v
}

/// Blobs on a 20-pixel grid of `rows` rows of six from (50, 40), each centroid moved by up
/// to `jitter` pixels, and their lattice.
fn jittered(rows: i32, jitter: f64) -> (Vec<Blob>, Lattice) {
    let wobble = [
        0.8, -1.0, 0.5, -0.3, 1.0, -0.6, 0.2, 0.9, -0.8, 0.4, -0.5, 0.7,
    ];
    let mut blobs = Vec::new();
    let mut lat = Vec::new();
    for r in 0..rows {
        for c in 0..6 {
            let k = (r * 6 + c) as usize;
            blobs.push(Blob {
                c: [
                    50.0 + 20.0 * c as f64 + jitter * wobble[k % 12],
                    40.0 + 20.0 * r as f64 - jitter * wobble[(k + 5) % 12],
                ],
                area: 196.0,
            });
            lat.push((k, [c, r]));
        }
    }
    (blobs, lat)
}

#[test]
fn cells_placed_from_too_little_lattice_are_uncertain() {
    let kind = ChartKind::Cc24;
    let place = |blobs: &[Blob], lat: &Lattice| {
        let map = placement_map(false, 1.0, 1.0, 0, 0);
        Placement {
            score: 1.0,
            hc: fit_lattice(blobs, lat).unwrap().then_after(&map),
            mirrored: false,
            outside: 0,
            enclosed: lat.len() == 24,
            map,
            window: ([0, 0], [6, 4]),
        }
    };
    let x = |rows: i32, jitter: f64| {
        let (blobs, lat) = jittered(rows, jitter);
        extrapolation(&blobs, &lat, &place(&blobs, &lat), kind)
    };
    // Every cell seen: nothing is placed by the fit alone.
    assert_eq!(x(4, 1.0), 0.0);
    // Centroids exactly on a grid: dropping a point moves nothing.
    assert!(x(2, 0.0) < 1e-6, "{}", x(2, 0.0));
    // Two rows seen, centroids up to 0.15 pitch off (patches partly covered, or blurred into
    // a neighbour): the projective terms that place the other two rows hang on single points
    // (0.31 pitch).
    let two = x(2, 3.0);
    assert!(two > EXTRAPOLATION_LIMIT, "{two}");
    // Three rows seen with the same errors: the fourth row moves less (0.17), yet more than
    // the limit; with centroids up to 0.05 pitch off it is pinned well enough.
    let three = x(3, 3.0);
    assert!(
        three < two && three > EXTRAPOLATION_LIMIT,
        "{three} vs {two}"
    );
    let tight = x(3, 1.0);
    assert!(tight < EXTRAPOLATION_LIMIT, "{tight}");
}

#[test]
fn downsample_takes_box_means_and_zeroes_non_finite_values() {
    let mut data = vec![0.0f32; 4 * 2 * 3];
    for (i, v) in data.iter_mut().enumerate() {
        *v = i as f32;
    }
    data[0] = f32::NAN;
    let f = Frame::from_data(4, 2, Layout::Rgb, data).unwrap();
    let (w, h, out) = downsample(&f, 2);
    assert_eq!((w, h), (2, 1));
    // Pixel (0,0) block: pixels 0, 1 (row 0) and 4, 5 (row 1); red = 0(NaN→0), 3, 12, 15.
    assert_eq!(out[0], (0.0 + 3.0 + 12.0 + 15.0) / 4.0);
    assert_eq!(out[3], (6.0 + 9.0 + 18.0 + 21.0) / 4.0);
}

#[test]
fn log_chroma_refuses_a_black_frame_and_is_exposure_free_in_chroma() {
    assert!(log_chroma(&[0.0; 12]).is_none());
    let (l1, r1, b1) = log_chroma(&[0.2, 0.4, 0.1, 1.0, 1.0, 1.0]).unwrap();
    let (l2, r2, b2) = log_chroma(&[0.4, 0.8, 0.2, 2.0, 2.0, 2.0]).unwrap();
    assert!((l2[0] - l1[0] - 2f32.ln()).abs() < 1e-5);
    assert!((r1[0] - r2[0]).abs() < 1e-4 && (b1[0] - b2[0]).abs() < 1e-4);
}

#[test]
fn flat_regions_and_their_shapes() {
    // A 40×20 mask: a filled 8×8 square and a 16×2 bar.
    let mut m = image::GrayImage::new(40, 20);
    for y in 4..12 {
        for x in 4..12 {
            m.put_pixel(x, y, image::Luma([255]));
        }
    }
    for y in 15..17 {
        for x in 20..36 {
            m.put_pixel(x, y, image::Luma([255]));
        }
    }
    let stats = region_moments(&m);
    let mut regions: Vec<&[f64; 6]> = stats.iter().skip(1).filter(|s| s[0] > 0.0).collect();
    regions.sort_by(|a, b| b[0].total_cmp(&a[0]));
    assert_eq!(regions.len(), 2);
    let (c, ok) = patch_shape(regions[0], 10.0, 100.0);
    assert!(ok, "the square is patch-like");
    assert_eq!(c, [8.0, 8.0]);
    assert!(
        !patch_shape(regions[1], 10.0, 100.0).1,
        "the 8:1 bar is not"
    );
    assert!(
        !patch_shape(regions[0], 10.0, 50.0).1,
        "above the largest area"
    );
}

#[test]
fn flat_mask_marks_uniform_pixels_only() {
    let (ws, hs) = (8, 8);
    let logl: Vec<f32> = (0..ws * hs)
        .map(|i| if i % ws < 4 { 0.0 } else { 1.0 })
        .collect();
    let p = Prepared {
        f: 1,
        ws,
        hs,
        small: vec![0.0; ws * hs * 3],
        logl,
        cr: vec![0.3; ws * hs],
        cb: vec![0.3; ws * hs],
    };
    let m = flat_mask(&p, 0.08);
    assert_eq!(m.get_pixel(1, 1).0[0], 255);
    assert_eq!(m.get_pixel(3, 3).0[0], 0, "next to the step");
    assert_eq!(m.get_pixel(0, 3).0[0], 0, "the border");
}

#[test]
fn the_walk_bridges_one_missed_patch() {
    let blobs = grid([50.0, 40.0], 20.0, 6, 4, &[(2, 1)]);
    let lats = lattices(&blobs);
    assert_eq!(lats.len(), 1);
    assert_eq!(lats[0].len(), 23);
    let (imin, imax, jmin, jmax) = extent(&lats[0]);
    assert_eq!((imax - imin, jmax - jmin), (5, 3));
}

#[test]
fn an_empty_line_splits_a_lattice() {
    // Two 6×4 pages whose columns are 2.3 pitches apart across the hinge: the double
    // step reaches across, the split separates them.
    let mut blobs = grid([300.0, 40.0], 20.0, 6, 4, &[]);
    blobs.extend(grid([300.0 - 7.3 * 20.0, 40.0], 20.0, 6, 4, &[]));
    let lats = lattices(&blobs);
    assert_eq!(lats.iter().map(Vec::len).collect::<Vec<_>>(), [24, 24]);
    for l in &lats {
        let (imin, imax, _, _) = extent(l);
        assert_eq!(imax - imin, 5);
    }
    // A missed patch is no empty line.
    let l: Lattice = vec![(0, [0, 0]), (1, [2, 0]), (2, [1, 1])];
    assert_eq!(split_gaps(l.clone()), vec![l]);
    // An empty column with 6 patches on one side and 7 on the other splits; with 5 on
    // one side it does not (a part too small to place).
    let side = |i0: i32, n: usize| (0..n).map(move |k| (k, [i0 + (k % 2) as i32, k as i32 / 2]));
    let l: Lattice = side(0, 6).chain(side(3, 7)).collect();
    let parts = split_gaps(l);
    assert_eq!(parts.iter().map(Vec::len).collect::<Vec<_>>(), [7, 6]);
    let l: Lattice = side(0, 5).chain(side(3, 7)).collect();
    assert_eq!(split_gaps(l).len(), 1);
}

#[test]
fn refine_keeps_the_page_and_fits_its_pitch() {
    let mut blobs = grid([300.0, 40.0], 20.0, 6, 4, &[]);
    blobs.extend(grid([300.0 - 7.3 * 20.0, 40.0], 20.0, 6, 4, &[]));
    let lat = lattices(&blobs).remove(0);
    let (lat, h) = refine(&blobs, lat, 6).unwrap();
    assert_eq!(lat.len(), 24);
    assert!((local_step(&h, 0, 0) - 20.0).abs() < 1e-6);
}

#[test]
fn points_outside_the_placement_are_dropped_from_the_fit() {
    // A 6×4 chart of pitch 20 and three stray points in the next column, 0.2 pitch off
    // the grid: the refit is the chart's own grid again.
    let mut blobs = grid([50.0, 40.0], 20.0, 6, 4, &[]);
    let mut lat: Lattice = (0..24).map(|k| (k, [k as i32 % 6, k as i32 / 6])).collect();
    for j in 0..3 {
        blobs.push(Blob {
            c: [50.0 + 6.0 * 20.0 + 4.0, 40.0 + 20.0 * j as f64],
            area: 196.0,
        });
        lat.push((24 + j, [6, j as i32]));
    }
    let h_all = fit_lattice(&blobs, &lat).unwrap();
    let map = placement_map(false, 1.0, 1.0, 0, 0);
    let best = Placement {
        score: 1.0,
        hc: h_all.then_after(&map),
        mirrored: false,
        outside: 0,
        enclosed: true,
        map,
        window: ([0, 0], [6, 4]),
    };
    let (kept, scored) = refit_inside(&blobs, lat, vec![best]);
    assert_eq!(kept.len(), 24);
    let p = scored[0].hc.apply([5.5, 3.5]);
    assert!(
        (p[0] - 150.0).abs() < 1e-6 && (p[1] - 100.0).abs() < 1e-6,
        "{p:?}"
    );
    let q = h_all.apply([5.0, 3.0]);
    assert!(
        (q[0] - 150.0).abs() > 0.1,
        "the strays did pull the first fit: {q:?}"
    );
}

#[test]
fn placement_map_puts_the_first_cell_on_the_origin_point() {
    for swap in [false, true] {
        for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
            let h = placement_map(swap, sx, sy, 3, -2);
            let p = h.apply([0.5, 0.5]);
            assert!((p[0] - 3.0).abs() < 1e-12 && (p[1] + 2.0).abs() < 1e-12);
        }
    }
}

#[test]
fn windows_hold_the_most_points() {
    let l: Lattice = (0..6).map(|i| (i as usize, [i, 0])).collect();
    assert_eq!(windows(&l, 0, 5, 4, 0), vec![0, 1, 2]);
    assert_eq!(windows(&l, 0, 5, 6, 0), vec![0]);
}

#[test]
fn judge_refuses_ambiguity_and_poor_matches() {
    let r = Reference::load(ChartKind::Cc24.default_reference(), ChartKind::Cc24, None).unwrap();
    let hc = Homography([20.0, 0.0, 10.0, 0.0, 20.0, 10.0, 0.0, 0.0, 1.0]);
    let p = |score: f64, enclosed: bool| Placement {
        score,
        hc,
        mirrored: false,
        outside: 0,
        enclosed,
        map: placement_map(false, 1.0, 1.0, 0, 0),
        window: ([0, 0], [6, 4]),
    };
    let judged = |scored: &[Placement], around: (usize, usize), spread: f64| {
        judge(&r, 24, scored, around, spread, &[])
    };
    let (best, runner, persp) = judged(&[p(1.0, false), p(3.0, false)], (0, 24), 0.0).unwrap();
    assert_eq!((best.score, runner), (1.0, 3.0));
    assert!((persp - 1.0).abs() < 1e-12);
    assert!(judged(&[p(1.0, false), p(1.2, false)], (0, 24), 0.0).is_err());
    assert!(judged(&[], (0, 24), 0.0).is_err());
    // Loosely matching: only with the outer ring all seen and a decisive runner-up.
    let loose = 0.5 * (DETECT_MATCH_LIMIT + MATCH_LIMIT);
    assert!(judged(&[p(loose, false), p(4.0 * loose, false)], (0, 24), 0.0).is_err());
    assert!(judged(&[p(loose, true), p(4.0 * loose, true)], (0, 24), 0.0).is_ok());
    // Decisive: a little beyond the limit with the next 2.5× worse and the hues kept, enclosed
    // or not; not with the hues lost, a close runner-up or a poorer match.
    let graded = 0.5 * (DETECT_MATCH_LIMIT + DECISIVE_MATCH_LIMIT);
    let kept = [vec![40.0, 35.0], vec![10.0; 10]].concat();
    let lost = [vec![40.0, 35.0, 31.0], vec![10.0; 9]].concat();
    let hued = |scored: &[Placement], hues: &[f64]| judge(&r, 23, scored, (0, 24), 0.0, hues);
    assert!(hues_hold(&kept) && !hues_hold(&lost) && !hues_hold(&[1.0; 7]));
    let next = graded / DECISIVE_RATIO;
    for enclosed in [false, true] {
        assert!(hued(&[p(graded, enclosed), p(next, false)], &kept).is_ok());
    }
    let refused = hued(&[p(graded, false), p(next, false)], &lost);
    assert!(
        matches!(&refused, Err(ChartError::NotFound(m)) if m.contains("9 of 12 colours")),
        "{refused:?}"
    );
    assert!(hued(&[p(graded, false), p(0.9 * next, false)], &kept).is_err());
    let poorer = DECISIVE_MATCH_LIMIT + 0.1;
    assert!(hued(
        &[p(poorer, false), p(poorer / DECISIVE_RATIO, false)],
        &kept
    )
    .is_err());
    assert!(hued(&[p(graded, false), p(graded / DECISIVE_RATIO, false)], &[]).is_err());
    // Strong perspective (1.8×, 2.7×): read within the limit, refused beyond it.
    let steep = |enclosed: bool, g: f64| Placement {
        hc: Homography([20.0, 0.0, 10.0, 0.0, 20.0, 10.0, g, 0.0, 1.0]),
        enclosed,
        ..p(1.0, false)
    };
    for enclosed in [false, true] {
        let (_, _, persp) = judged(&[steep(enclosed, 0.1), p(3.0, false)], (0, 24), 0.0).unwrap();
        assert!(persp > 1.6 && persp < PERSPECTIVE_LIMIT, "{persp}");
        let strong = judged(&[steep(enclosed, 0.2), p(3.0, false)], (0, 24), 0.0);
        assert!(
            matches!(&strong, Err(ChartError::NotFound(m)) if m.contains("strong perspective")),
            "{strong:?}"
        );
    }
    // Unseen cells of the ring placed uncertainly: refused; enclosed, not looked at.
    let spread = 2.0 * EXTRAPOLATION_LIMIT;
    assert!(judged(&[p(1.0, false), p(3.0, false)], (0, 24), spread).is_err());
    assert!(judged(&[p(1.0, true), p(3.0, true)], (0, 24), spread).is_ok());
    // A block of a larger grid (half the cells around it hold patches like its own).
    assert!(judged(&[p(1.0, true), p(3.0, true)], (11, 24), 0.0).is_ok());
    let larger = judged(&[p(1.0, true), p(3.0, true)], (12, 24), 0.0);
    assert!(
        matches!(&larger, Err(ChartError::NotFound(m)) if m.contains("larger chart")),
        "{larger:?}"
    );
    let mut out = p(1.0, true);
    out.outside = 2;
    assert!(matches!(
        judged(&[out, p(3.0, true)], (0, 24), 0.0),
        Err(ChartError::Geometry(_))
    ));
}
