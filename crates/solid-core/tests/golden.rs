//! Every case of shared/golden/descriptors.json, compared as docs/spec.md §7 says.

mod common;

use solid_lidar::{Config, Coord, Describer, Points, Scratch, Stats};

fn vecf(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn rel_l1(ours: &[f32], golden: &[f64]) -> f64 {
    assert_eq!(ours.len(), golden.len());
    let err: f64 = ours
        .iter()
        .zip(golden)
        .map(|(&o, &g)| (f64::from(o) - g).abs())
        .sum();
    let norm: f64 = golden.iter().map(|g| g.abs()).sum();
    if norm == 0.0 {
        err
    } else {
        err / norm
    }
}

/// The shared folder and its golden/descriptors.json, when the shared data is there.
fn golden() -> Option<(std::path::PathBuf, serde_json::Value)> {
    let shared = common::shared()?;
    let text = std::fs::read_to_string(shared.join("golden/descriptors.json")).unwrap();
    Some((shared, serde_json::from_str(&text).unwrap()))
}

#[test]
fn golden_descriptors_match() {
    let Some((shared, doc)) = golden() else {
        return;
    };
    let cases = doc["cases"].as_array().unwrap();
    assert!(cases.len() >= 50, "only {} golden cases", cases.len());
    let mut worst: f64 = 0.0;
    for case in cases {
        let file = case["file"].as_str().unwrap();
        let c = &case["config"];
        let cfg = Config {
            n_range: c["n_range"].as_u64().unwrap() as usize,
            n_azimuth: c["n_azimuth"].as_u64().unwrap() as usize,
            n_elevation: c["n_elevation"].as_u64().unwrap() as usize,
            fov_up: c["fov_up"].as_f64().unwrap(),
            fov_down: c["fov_down"].as_f64().unwrap(),
            min_range: c["min_range"].as_f64().unwrap(),
            max_range: c["max_range"].as_f64().unwrap(),
            voxel_size: c["voxel_size"].as_f64().unwrap(),
        };
        // The named preset agrees with the config recorded in the golden file, voxel aside.
        let preset = Config::preset(case["preset"].as_str().unwrap()).unwrap();
        assert_eq!(
            Config {
                voxel_size: cfg.voxel_size,
                ..preset
            },
            cfg,
            "{file}"
        );

        let xyz = common::read_scan(&shared.join(file));
        let d = Describer::new(cfg)
            .unwrap()
            .describe(Points::new(&xyz, 3).unwrap())
            .unwrap();
        let ctx = format!("{file} voxel {}", cfg.voxel_size);
        assert_eq!(
            d.stats.n_points as u64,
            case["n_points"].as_u64().unwrap(),
            "{ctx}"
        );
        assert_eq!(
            d.stats.n_in_range as u64,
            case["n_in_range"].as_u64().unwrap(),
            "{ctx}"
        );
        let kept = case["n_kept"].as_u64().unwrap() as f64;
        assert!(
            (d.stats.n_kept as f64 - kept).abs() <= 1e-3 * kept,
            "{ctx}: kept {} vs golden {kept}",
            d.stats.n_kept
        );
        let er = rel_l1(&d.r, &vecf(&case["r_solid"]));
        let ea = rel_l1(&d.a, &vecf(&case["a_solid"]));
        assert!(
            er <= 1e-3 && ea <= 1e-3,
            "{ctx}: relative L1 error r {er:e}, a {ea:e}"
        );
        worst = worst.max(er).max(ea);
    }
    eprintln!(
        "{} golden cases match; worst relative L1 error {worst:e}",
        cases.len()
    );
}

/// The statistics and the bits of R and A from the dispatched `describe` or its portable copy.
fn describe_bits<T: Coord>(
    portable: bool,
    points: Points<'_, T>,
    cfg: &Config,
    scratch: &mut [Scratch],
) -> (Stats, Vec<u32>, Vec<u32>) {
    let (mut r, mut a) = (vec![0f32; cfg.n_range], vec![0f32; cfg.n_azimuth]);
    let describe = if portable {
        solid_lidar::stages::describe_portable::<T>
    } else {
        solid_lidar::describe::<T>
    };
    let stats = describe(points, cfg, scratch, &mut r, &mut a).unwrap();
    let bits = |v: Vec<f32>| v.iter().map(|x| x.to_bits()).collect();
    (stats, bits(r), bits(a))
}

/// Every compiled copy of `describe` (AVX2 where the CPU has it, portable) gives the same bits.
#[test]
fn dispatched_and_portable_describe_give_the_same_bits() {
    let Some((shared, doc)) = golden() else {
        return;
    };
    for case in doc["cases"].as_array().unwrap() {
        let file = case["file"].as_str().unwrap();
        let xyz = common::read_scan(&shared.join(file));
        let f32s: Vec<f32> = xyz.iter().map(|&v| v as f32).collect();
        let voxel = case["config"]["voxel_size"].as_f64().unwrap();
        let preset = Config::preset(case["preset"].as_str().unwrap()).unwrap();
        let cfg = Config {
            voxel_size: voxel,
            ..preset
        };
        let mut scratch = vec![0u64; solid_lidar::describe_scratch_len(xyz.len() / 3, &cfg)];
        let run = |portable: bool, scratch: &mut [u64], wide: bool| {
            if wide {
                describe_bits(portable, Points::new(&xyz, 3).unwrap(), &cfg, scratch)
            } else {
                describe_bits(portable, Points::new(&f32s, 3).unwrap(), &cfg, scratch)
            }
        };
        for wide in [true, false] {
            assert_eq!(
                run(true, &mut scratch, wide),
                run(false, &mut scratch, wide),
                "{file} voxel {voxel}"
            );
        }
    }
}

#[test]
fn f32_and_f64_input_agree_on_kitti() {
    let Some(shared) = common::shared() else {
        return;
    };
    let raw = common::read_kitti(&shared.join("data/kitti00/velodyne/000000.bin"));
    let wide: Vec<f64> = raw.iter().map(|&v| f64::from(v)).collect();
    let mut desc = Describer::new(Config::preset("hdl64").unwrap()).unwrap();
    let a = desc.describe(Points::new(&raw, 4).unwrap()).unwrap();
    let b = desc.describe(Points::new(&wide, 4).unwrap()).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.stats.n_points, 124_668);
}
