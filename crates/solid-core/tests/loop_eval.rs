//! Loop closure on the HKU Livox Avia sequence (docs/spec.md §5): Recall@1 of the loop detector with and
//! without A-SOLiD re-ranking, and with places sent in the quantised wire form.
//!
//! Prints its figures (`cargo test -p solid-lidar --test loop_eval -- --nocapture`) and asserts
//! the properties the library relies on: the detector equals plain exact search when it does not
//! re-rank, and the quantised wire form keeps Recall@1 within 2 points of float32.
#![cfg(feature = "std")]

mod common;
use common::{data_dir, read_xyz_f32};

use solid_lidar::db::{decode_place, encode_place, DetectorConfig, LoopDetector};
use solid_lidar::eval::{score, Queries, NO_CANDIDATE};
use solid_lidar::{Config, Describer, Descriptor, Points};

struct Sequence {
    descriptors: Vec<Descriptor>,
    poses: Vec<[f64; 12]>,
}

fn load(cfg: &Config) -> Option<Sequence> {
    let dir = data_dir()?.join("hku1-avia");
    let poses: Vec<[f64; 12]> = std::fs::read_to_string(dir.join("odom_poses.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|v| v.parse().unwrap()).collect();
            v.try_into().unwrap()
        })
        .collect();
    let mut describer = Describer::new(*cfg).unwrap();
    let descriptors: Vec<Descriptor> = (0..poses.len())
        .map(|i| {
            let xyz = read_xyz_f32(&dir.join(format!("Scans/{i:06}.pcd")));
            describer.describe(Points::new(&xyz, 3).unwrap()).unwrap()
        })
        .collect();
    Some(Sequence { descriptors, poses })
}

struct Result1 {
    recall: [f64; 2],
    positives: [usize; 2],
    rot_err_deg: f64,
}

/// Runs a detector over the sequence and scores its candidates (docs/spec.md §5, `eval::score`) at
/// radii 3 m and 5 m.
fn run(seq: &Sequence, cfg: &Config, rerank: bool, quantized: bool) -> Result1 {
    let mut det = LoopDetector::new(
        *cfg,
        DetectorConfig {
            threshold: 1.0,
            rerank,
            ..unverified()
        },
    )
    .unwrap();
    let (mut query, mut eligible, mut ids, mut score_, mut heading) =
        (vec![], vec![], vec![], vec![], vec![]);
    let k = det.config().top_k;
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
        let step = det.detect(&d, q as f64, None).unwrap();
        assert_eq!(step.query as usize, q);
        assert_eq!(step.eligible as usize, q.saturating_sub(50));
        if step.eligible == 0 {
            assert!(step.accepted.is_none() && step.candidates.is_empty());
            continue;
        }
        let lp = step.accepted.expect("threshold 1 accepts every top-1");
        assert_eq!(lp.candidate, step.candidates[0].id);
        assert!((lp.candidate as usize) < q - 50);
        query.push(step.query);
        eligible.push(step.eligible);
        score_.push(lp.score);
        heading.push(lp.heading_deg);
        ids.extend((0..k).map(|i| step.candidates.get(i).map_or(NO_CANDIDATE, |c| c.id)));
    }
    let queries = Queries {
        query: &query,
        eligible: &eligible,
        k,
        ids: &ids,
        score: &score_,
        heading_deg: &heading,
        pose: &[],
    };
    let e3 = score(&queries, &seq.poses, 3.0).unwrap();
    let e5 = score(&queries, &seq.poses, 5.0).unwrap();
    let errs = e5.rotation_errors();
    Result1 {
        recall: [e3.recall_at(1).unwrap(), e5.recall_at(1).unwrap()],
        positives: [e3.n_gt(), e5.n_gt()],
        rot_err_deg: errs.iter().sum::<f64>() / errs.len().max(1) as f64,
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

/// The detector defaults without verification (these tests feed descriptors, not points).
fn unverified() -> DetectorConfig {
    let mut c = DetectorConfig::default();
    c.verify.enabled = false;
    c
}
