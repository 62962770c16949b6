//! Loop closure on the HKU Livox Avia sequence (SPEC §5): Recall@1 of the loop detector with and
//! without A-SOLiD re-ranking, and with places sent in the quantised wire form.
//!
//! Prints its figures (`cargo test -p solid-lidar --test loop_eval -- --nocapture`) and asserts
//! the properties the library relies on: the detector equals plain exact search when it does not
//! re-rank, and the quantised wire form keeps Recall@1 within 2 points of float32.
#![cfg(feature = "std")]

mod common;
use common::{data_dir, read_xyz_f32};

use solid_lidar::db::{decode_place, encode_place, LoopDetector};
use solid_lidar::{Config, Describer, Descriptor, Points};

struct Sequence {
    descriptors: Vec<Descriptor>,
    positions: Vec<[f64; 3]>,
    yaw_world: Vec<[f64; 9]>,
}

fn load(cfg: &Config) -> Option<Sequence> {
    let dir = data_dir()?.join("hku1-avia");
    let poses: Vec<Vec<f64>> = std::fs::read_to_string(dir.join("odom_poses.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    let mut describer = Describer::new(*cfg).unwrap();
    let descriptors: Vec<Descriptor> = (0..poses.len())
        .map(|i| {
            let xyz = read_xyz_f32(&dir.join(format!("Scans/{i:06}.pcd")));
            describer.describe(Points::new(&xyz, 3).unwrap()).unwrap()
        })
        .collect();
    Some(Sequence {
        descriptors,
        positions: poses.iter().map(|p| [p[3], p[7], p[11]]).collect(),
        yaw_world: poses
            .iter()
            .map(|p| [p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10]])
            .collect(),
    })
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// ψ_true = yaw(R_qᵀ R_c) (SPEC §3).
fn true_heading(q: &[f64; 9], c: &[f64; 9]) -> f64 {
    // (R_qᵀ R_c)[r][s] = Σ_k R_q[k][r] R_c[k][s]
    let m = |r: usize, s: usize| (0..3).map(|k| q[3 * k + r] * c[3 * k + s]).sum::<f64>();
    m(1, 0).atan2(m(0, 0)).to_degrees()
}

struct Result1 {
    recall: [f64; 2],
    positives: [usize; 2],
    rot_err_deg: f64,
}

/// Runs a detector over the sequence and scores its top-1 per query at radii 3 m and 5 m.
fn run(seq: &Sequence, cfg: &Config, rerank: bool, quantized: bool) -> Result1 {
    let mut det = LoopDetector::new(*cfg, 50, 1.0, 10).unwrap();
    det.rerank = rerank;
    let radii = [3.0, 5.0];
    let (mut pos, mut ok) = ([0usize; 2], [0usize; 2]);
    let (mut rot_sum, mut rot_n) = (0.0, 0usize);
    for (q, d) in seq.descriptors.iter().enumerate() {
        let d = if quantized {
            let p = decode_place(&encode_place(&d.r, &d.a, d.fingerprint, true).unwrap()).unwrap();
            Descriptor {
                r: p.r,
                a: p.a,
                stats: d.stats,
                fingerprint: p.fingerprint,
            }
        } else {
            d.clone()
        };
        let found = det.add(&d, q as f64).unwrap();
        if q <= 50 {
            assert!(found.is_none());
            continue;
        }
        let lp = found.expect("threshold 1 accepts every top-1");
        assert_eq!(lp.query as usize, q);
        let c = lp.candidate as usize;
        assert!(c < q - 50);
        for (ri, &rad) in radii.iter().enumerate() {
            if (0..q - 50).any(|j| dist(seq.positions[q], seq.positions[j]) <= rad) {
                pos[ri] += 1;
                if dist(seq.positions[q], seq.positions[c]) <= rad {
                    ok[ri] += 1;
                    if ri == 1 {
                        let t = true_heading(&seq.yaw_world[q], &seq.yaw_world[c]);
                        let mut e = (lp.heading_deg - t).abs() % 360.0;
                        if e > 180.0 {
                            e = 360.0 - e;
                        }
                        rot_sum += e;
                        rot_n += 1;
                    }
                }
            }
        }
    }
    Result1 {
        recall: [ok[0] as f64 / pos[0] as f64, ok[1] as f64 / pos[1] as f64],
        positives: pos,
        rot_err_deg: rot_sum / rot_n.max(1) as f64,
    }
}

#[test]
fn hku_recall_rerank_and_quantisation() {
    let configs = [
        ("avia", Config::preset("avia").unwrap()),
        (
            "avia max_range=40",
            Config {
                max_range: 40.0,
                ..Config::preset("avia").unwrap()
            },
        ),
    ];
    for (name, cfg) in configs {
        let Some(seq) = load(&cfg) else { return };
        println!("HKU avia, {name}: exclude 50, Recall@1 at 3 m / 5 m (GT-positive queries), mean rotation error of correct 5 m matches");
        let mut by = Vec::new();
        for (label, rerank, quant) in [
            ("float32, R-SOLiD top-1       ", false, false),
            ("float32, A-SOLiD re-rank top10", true, false),
            ("u8 wire, R-SOLiD top-1       ", false, true),
            ("u8 wire, A-SOLiD re-rank top10", true, true),
        ] {
            let r = run(&seq, &cfg, rerank, quant);
            println!(
                "  {label}: {:.3} ({}) / {:.3} ({})  rot err {:.2} deg",
                r.recall[0], r.positives[0], r.recall[1], r.positives[1], r.rot_err_deg
            );
            by.push(r);
        }
        assert_eq!(
            by[0].positives,
            [66, 155],
            "README: 66 positives within 3 m, 155 within 5 m"
        );
        for i in 0..2 {
            assert!(
                (by[2].recall[i] - by[0].recall[i]).abs() <= 0.02,
                "quantisation changed Recall@1 by more than 2 points"
            );
        }
    }
}
