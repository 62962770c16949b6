//! The C API's describe against the Rust call, in one process (`make c-bench`): the medians of
//! interleaved calls on the same points, their ratio (issue 28: within 5 %), and the bytes the C
//! call allocates once warm (0: contiguous float32 x y z and x y z intensity are read in place,
//! never copied).

use std::alloc::{GlobalAlloc, Layout, System};
use std::ffi::c_void;
use std::ptr::null_mut;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::time::Instant;

use solid::describe::{solid_describe, solid_describer_new, SolidDescriber};
use solid::{SolidPoints, SolidStatus};
use solid_lidar::{describe, describe_scratch_len, Config, Points};
use solid_lidar_benches::kitti;

/// Counts the bytes allocated, to show that a warm C call allocates nothing.
struct Counting;

static ALLOCATED: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCATED.fetch_add(l.size(), Relaxed);
        System.alloc(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        System.dealloc(p, l)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

type DescribeFn = unsafe extern "C" fn(
    *const SolidDescriber,
    *const SolidPoints,
    *mut f32,
    usize,
    *mut f32,
    usize,
    *mut solid::describe::SolidDescribeStats,
) -> SolidStatus;

fn main() {
    let preset = "hdl64";
    let cfg = Config::preset(preset).unwrap();
    let mut c_cfg = null_mut();
    let name = std::ffi::CString::new(preset).unwrap();
    let mut describer = null_mut();
    unsafe {
        assert_eq!(
            solid::config::solid_config_new(name.as_ptr(), &mut c_cfg),
            SolidStatus::Ok
        );
        assert_eq!(solid_describer_new(c_cfg, &mut describer), SolidStatus::Ok);
    }
    // Through a pointer the optimiser cannot see through, as a C caller reaches it.
    let c_describe: DescribeFn = std::hint::black_box(solid_describe);
    println!("describe, {preset}, single call per sample, medians of interleaved samples");
    println!(
        "{:<34} {:>9} {:>9} {:>7} {:>13}",
        "input", "Rust ms", "C ms", "C/Rust", "C alloc bytes"
    );
    for (label, rel) in [
        ("KITTI 000000 full", "kitti00/velodyne/000000.bin"),
        (
            "KITTI 000000 60° clip",
            "solid-samples/kitti_00_60/000000.bin",
        ),
    ] {
        let xyzi = kitti(rel);
        let xyz: Vec<f32> = xyzi
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        for (layout, data, stride) in [("xyzi", &xyzi, 4usize), ("xyz", &xyz, 3)] {
            let points = Points::new(data, stride).unwrap();
            let c_points = SolidPoints {
                data: data.as_ptr().cast::<c_void>(),
                count: points.len(),
                stride_bytes: stride * 4,
                coord_bytes: 4,
            };
            let mut scratch = vec![0u64; describe_scratch_len(points.len(), &cfg)];
            let (mut r, mut a) = (vec![0f32; cfg.n_range], vec![0f32; cfg.n_azimuth]);
            let (mut rc, mut ac) = (r.clone(), a.clone());
            let mut rust = || {
                describe(points, &cfg, &mut scratch, &mut r, &mut a).unwrap();
            };
            let mut c = || unsafe {
                let s = c_describe(
                    describer,
                    &c_points,
                    rc.as_mut_ptr(),
                    rc.len(),
                    ac.as_mut_ptr(),
                    ac.len(),
                    null_mut(),
                );
                assert_eq!(s, SolidStatus::Ok);
            };
            rust();
            c();
            let before = ALLOCATED.load(Relaxed);
            c();
            let c_alloc = ALLOCATED.load(Relaxed) - before;
            let (mut tr, mut tc) = (Vec::new(), Vec::new());
            for i in 0..200 {
                // Alternate which goes first, so that neither always finds the caches warm.
                let time = |f: &mut dyn FnMut(), out: &mut Vec<f64>| {
                    let t0 = Instant::now();
                    f();
                    out.push(t0.elapsed().as_secs_f64());
                };
                if i % 2 == 0 {
                    time(&mut rust, &mut tr);
                    time(&mut c, &mut tc);
                } else {
                    time(&mut c, &mut tc);
                    time(&mut rust, &mut tr);
                }
            }
            let med = |v: &mut Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            };
            let (mr, mc) = (med(&mut tr), med(&mut tc));
            assert_eq!(
                (&rc, &ac),
                (&r, &a),
                "the C call gives the Rust call's bits"
            );
            println!(
                "{:<34} {:>9.3} {:>9.3} {:>7.3} {:>13}",
                format!("{label}, {layout}"),
                mr * 1e3,
                mc * 1e3,
                mc / mr,
                c_alloc
            );
        }
    }
    unsafe {
        solid::describe::solid_describer_free(describer);
        solid::config::solid_config_free(c_cfg);
    }
}
