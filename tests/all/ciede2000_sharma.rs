//! CIEDE2000 against all 34 pairs of Sharma, Wu & Dalal (2005), Table 1.

use nsrm::ciede2000;

#[test]
fn all_34_sharma_pairs_to_1e_4() {
    let text = include_str!("../data/sharma2005_ciede2000_pairs.csv");
    let mut n = 0;
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let v: Vec<f64> = line.split(',').map(|c| c.trim().parse().unwrap()).collect();
        assert_eq!(v.len(), 8, "{line}");
        let d = ciede2000([v[1], v[2], v[3]], [v[4], v[5], v[6]]);
        assert!(
            (d - v[7]).abs() <= 1e-4,
            "pair {}: got {d:.6}, want {}",
            v[0],
            v[7]
        );
        // Symmetric.
        let d2 = ciede2000([v[4], v[5], v[6]], [v[1], v[2], v[3]]);
        assert!((d - d2).abs() < 1e-12);
        n += 1;
    }
    assert_eq!(n, 34);
}
