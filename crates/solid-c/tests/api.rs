//! The C ABI called as C calls it: statuses, messages, in-place points, and that its results are
//! the core's.

use std::ffi::{c_char, c_void, CStr, CString};
use std::ptr::{null, null_mut};

use solid::config::*;
use solid::database::*;
use solid::describe::*;
use solid::detector::*;
use solid::registration::*;
use solid::*;

fn last_error() -> String {
    unsafe { CStr::from_ptr(solid_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn c(s: &str) -> CString {
    CString::new(s).unwrap()
}

/// A scan with structure: a box room with a floor and a wall across, x y z intensity per point.
fn room(shift: f64) -> Vec<f32> {
    let mut v = Vec::new();
    for i in 0..60 {
        for j in 0..12 {
            let (u, h) = (i as f64 * 0.5 - 15.0, j as f64 * 0.5 - 2.0);
            for (x, y) in [
                (u, -8.0),
                (u, 8.0),
                (-15.0, u * 0.5),
                (15.0, u * 0.5),
                (4.0, u * 0.1),
            ] {
                v.extend([(x + shift) as f32, y as f32, h as f32, 1.0]);
            }
            // The floor, under the walls.
            let w = j as f64 * 1.3 - 7.5;
            v.extend([(u + shift) as f32, w as f32, -2.0, 1.0]);
        }
    }
    v
}

fn points(xyzi: &[f32]) -> SolidPoints {
    SolidPoints {
        data: xyzi.as_ptr().cast::<c_void>(),
        count: xyzi.len() / 4,
        stride_bytes: 16,
        coord_bytes: 4,
    }
}

fn config(preset: &str) -> *mut SolidConfig {
    let mut cfg = null_mut();
    assert_eq!(
        unsafe { solid_config_new(c(preset).as_ptr(), &mut cfg) },
        SolidStatus::Ok
    );
    cfg
}

#[test]
fn describe_reads_strided_points_in_place_and_equals_the_core() {
    let scan = room(0.0);
    let cfg = config("vlp16");
    let mut d = null_mut();
    unsafe {
        assert_eq!(solid_describer_new(cfg, &mut d), SolidStatus::Ok);
        let (mut r, mut a) = (vec![0f32; 40], vec![0f32; 60]);
        let mut st = SolidDescribeStats::default();
        let pts = points(&scan);
        let s = solid_describe(d, &pts, r.as_mut_ptr(), 40, a.as_mut_ptr(), 60, &mut st);
        assert_eq!(s, SolidStatus::Ok);
        let want = solid_lidar::Describer::new(solid_lidar::Config::preset("vlp16").unwrap())
            .unwrap()
            .describe(solid_lidar::Points::new(&scan, 4).unwrap())
            .unwrap();
        assert_eq!((r, a), (want.r.clone(), want.a.clone()));
        assert_eq!(st.n_kept, want.stats.n_kept);
        // The same points as float64 x y z give the same bits (docs/spec.md §2).
        let xyz: Vec<f64> = scan
            .chunks(4)
            .flat_map(|p| p[..3].iter().map(|&v| f64::from(v)))
            .collect();
        let pts64 = SolidPoints {
            data: xyz.as_ptr().cast(),
            count: xyz.len() / 3,
            stride_bytes: 24,
            coord_bytes: 8,
        };
        let (mut r2, mut a2) = (vec![0f32; 40], vec![0f32; 60]);
        let s = solid_describe(
            d,
            &pts64,
            r2.as_mut_ptr(),
            40,
            a2.as_mut_ptr(),
            60,
            null_mut(),
        );
        assert_eq!(s, SolidStatus::Ok);
        assert_eq!((&r2, &a2), (&want.r, &want.a));
        // A short output buffer is refused and named.
        let mut short = vec![0f32; 39];
        let s = solid_describe(
            d,
            &pts,
            short.as_mut_ptr(),
            39,
            a2.as_mut_ptr(),
            60,
            null_mut(),
        );
        assert_eq!(s, SolidStatus::BufferTooSmall);
        assert!(
            last_error().starts_with("solid_describe: "),
            "{}",
            last_error()
        );
        solid_describer_free(d);
        solid_config_free(cfg);
    }
}

#[test]
fn bad_point_buffers_are_named_errors() {
    let scan = room(0.0);
    let cfg = config("hdl64");
    let mut d = null_mut();
    let (mut r, mut a) = (vec![0f32; 40], vec![0f32; 60]);
    unsafe {
        solid_describer_new(cfg, &mut d);
        let mut run = |p: SolidPoints| {
            solid_describe(d, &p, r.as_mut_ptr(), 40, a.as_mut_ptr(), 60, null_mut())
        };
        let good = points(&scan);
        let misaligned = SolidPoints {
            data: scan.as_ptr().cast::<u8>().wrapping_add(1).cast(),
            ..good
        };
        assert_eq!(run(misaligned), SolidStatus::InvalidArgument);
        assert!(last_error().contains("aligned"), "{}", last_error());
        assert_eq!(
            run(SolidPoints {
                stride_bytes: 10,
                ..good
            }),
            SolidStatus::InvalidArgument
        );
        assert!(
            last_error().contains("stride_bytes = 10"),
            "{}",
            last_error()
        );
        assert_eq!(
            run(SolidPoints {
                coord_bytes: 2,
                ..good
            }),
            SolidStatus::InvalidArgument
        );
        assert_eq!(
            run(SolidPoints {
                data: null(),
                ..good
            }),
            SolidStatus::InvalidArgument
        );
        assert_eq!(
            run(SolidPoints {
                data: null(),
                count: 0,
                ..good
            }),
            SolidStatus::Ok
        );
        assert_eq!(
            solid_describe(
                d,
                null(),
                r.as_mut_ptr(),
                40,
                a.as_mut_ptr(),
                60,
                null_mut()
            ),
            SolidStatus::InvalidArgument
        );
        assert_eq!(last_error(), "solid_describe: points is NULL");
        solid_describer_free(d);
        solid_config_free(cfg);
    }
}

/// Sets parameter `name` of `handle` to `value` with `set`, reads it back with `get`: both
/// succeed and the value is kept.
unsafe fn set_and_read<T>(
    handle: *mut T,
    set: unsafe extern "C" fn(*mut T, *const c_char, f64) -> SolidStatus,
    get: unsafe extern "C" fn(*const T, *const c_char, *mut f64) -> SolidStatus,
    name: &str,
    value: f64,
) {
    let name = c(name);
    assert_eq!(set(handle, name.as_ptr(), value), SolidStatus::Ok);
    let mut v = f64::NAN;
    assert_eq!(get(handle, name.as_ptr(), &mut v), SolidStatus::Ok);
    assert_eq!(v, value);
}

#[test]
fn parameters_by_name_are_checked_and_kept_on_error() {
    let cfg = config("avia");
    let mut v = 0.0;
    unsafe {
        set_and_read(cfg, solid_config_set, solid_config_get, "max_range", 40.0);
        assert_eq!(
            solid_config_set(cfg, c("n_range").as_ptr(), 0.0),
            SolidStatus::InvalidParameter
        );
        assert!(last_error().contains("n_range"), "{}", last_error());
        assert_eq!(
            solid_config_set(cfg, c("n_range").as_ptr(), 2.5),
            SolidStatus::InvalidParameter
        );
        solid_config_get(cfg, c("n_range").as_ptr(), &mut v);
        assert_eq!(v, 40.0, "the old value stays");
        assert_eq!(
            solid_config_set(cfg, c("no_such").as_ptr(), 1.0),
            SolidStatus::InvalidArgument
        );
        assert!(last_error().contains("no_such"));
        assert_eq!(
            solid_config_new(c("nope").as_ptr(), &mut null_mut()),
            SolidStatus::InvalidParameter
        );
        solid_config_free(cfg);

        let mut dc = null_mut();
        assert_eq!(
            solid_detector_config_new(c("avia").as_ptr(), &mut dc),
            SolidStatus::Ok
        );
        let (set, get) = (solid_detector_config_set, solid_detector_config_get);
        set_and_read(dc, set, get, "verify", 0.0);
        assert_eq!(
            solid_detector_config_set(dc, c("verify").as_ptr(), 2.0),
            SolidStatus::InvalidParameter
        );
        // The registration and the gate of the detector, by prefix.
        set_and_read(dc, set, get, "gate.max_translation", 3.0);
        let nb = c("registration.neighbors");
        assert_eq!(
            solid_detector_config_set(dc, nb.as_ptr(), 2.0),
            SolidStatus::InvalidParameter
        );
        assert!(last_error().contains("neighbors"), "{}", last_error());
        let (f, p2p) = (c("registration.factor"), c("point-to-plane"));
        assert_eq!(
            solid_detector_config_set(dc, f.as_ptr(), 1.0),
            SolidStatus::InvalidParameter
        );
        assert_eq!(
            solid_detector_config_set_name(dc, f.as_ptr(), p2p.as_ptr()),
            SolidStatus::Ok
        );
        let nope = c("nope");
        assert_eq!(
            solid_detector_config_set_name(dc, f.as_ptr(), nope.as_ptr()),
            SolidStatus::InvalidParameter
        );
        // A parameter since removed is refused as Python refuses it (a config.json naming one
        // loads without it there, with a warning), the message saying so and why; nothing changes.
        let removed = c("view_min_overlap_deg");
        assert_eq!(
            solid_detector_config_set(dc, removed.as_ptr(), 20.0),
            SolidStatus::InvalidArgument
        );
        let said = last_error();
        assert!(
            said.contains("\"view_min_overlap_deg\" was removed in solid 0.1.0: ")
                && said.contains("the view check was removed")
                && said.contains("nothing replaces it")
                && !said.contains("config.json"),
            "{said}"
        );
        let mut v = 0.0;
        assert_eq!(
            solid_detector_config_get(dc, removed.as_ptr(), &mut v),
            SolidStatus::InvalidArgument
        );
        assert!(last_error().contains("was removed in solid 0.1.0: "));
        assert_eq!(
            solid_detector_config_set(dc, c("no_such_key").as_ptr(), 1.0),
            SolidStatus::InvalidArgument
        );
        assert!(
            last_error().contains("unknown parameter"),
            "{}",
            last_error()
        );
        solid_detector_config_free(dc);
    }
}

/// Adds an hdl64 descriptor (R 40, A 60 values) to session 0 of `db`.
unsafe fn add_hdl64(
    db: *mut SolidDatabase,
    r: &[f32; 40],
    a: &[f32; 60],
    timestamp: f64,
    pose: *const f64,
    id: *mut u32,
) -> SolidStatus {
    solid_database_add(db, r.as_ptr(), 40, a.as_ptr(), 60, 0, timestamp, pose, id)
}

#[test]
fn database_adds_searches_saves_and_loads() {
    let cfg = config("hdl64");
    let mut db = null_mut();
    let dir = std::env::temp_dir().join(format!("solid-c-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = c(dir.join("db.solid").to_str().unwrap());
    unsafe {
        assert_eq!(solid_database_new(cfg, &mut db), SolidStatus::Ok);
        let a = [1f32; 60];
        for i in 0..5 {
            let mut r = [0f32; 40];
            r[i] = 1.0;
            let mut id = 99;
            let pose = [
                1.0, 0.0, 0.0, i as f64, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
            ];
            let s = add_hdl64(db, &r, &a, i as f64, pose.as_ptr(), &mut id);
            assert_eq!((s, id), (SolidStatus::Ok, i as u32));
        }
        // A column-major pose (translation in the last row) is refused.
        let bad = [
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 3.0, 0.0, 0.0, 1.0,
        ];
        let r = [1f32; 40];
        let s = add_hdl64(db, &r, &a, f64::NAN, bad.as_ptr(), null_mut());
        assert_eq!(s, SolidStatus::InvalidParameter);
        assert!(last_error().contains("column-major"), "{}", last_error());
        let mut q = [0f32; 40];
        q[3] = 1.0;
        let mut hits = [SolidNeighbor::default(); 3];
        let mut found = 0;
        assert_eq!(
            solid_database_search(db, q.as_ptr(), 40, 3, 0, hits.as_mut_ptr(), &mut found),
            SolidStatus::Ok
        );
        assert_eq!((found, hits[0].id, hits[0].distance), (3, 3, 0.0));
        assert_eq!(solid_database_save(db, path.as_ptr()), SolidStatus::Ok);
        let mut back = null_mut();
        assert_eq!(
            solid_database_load(path.as_ptr(), &mut back),
            SolidStatus::Ok
        );
        let (mut n, mut session, mut t, mut pose) = (0, 9, 0.0, [0.0; 16]);
        solid_database_len(back, &mut n);
        assert_eq!(n, 5);
        assert_eq!(
            solid_database_entry(back, 2, &mut session, &mut t, pose.as_mut_ptr()),
            SolidStatus::Ok
        );
        assert_eq!((session, t, pose[3], pose[15]), (0, 2.0, 2.0, 1.0));
        assert_eq!(
            solid_database_entry(back, 5, &mut session, &mut t, null_mut()),
            SolidStatus::InvalidArgument
        );
        // A detector over the map shares its places: its scan follows them, the map stays as it
        // was, and an add to the map afterwards does not reach the detector.
        let (mut dc, mut det) = (null_mut(), null_mut());
        solid_detector_config_new(c("hdl64").as_ptr(), &mut dc);
        solid_detector_config_set(dc, c("verify").as_ptr(), 0.0);
        assert_eq!(
            solid_detector_from_database(back, dc, &mut det),
            SolidStatus::Ok
        );
        let mut lp = std::mem::MaybeUninit::<SolidLoop>::uninit();
        let mut found = false;
        let scan = room(0.0);
        let s = solid_detector_add(
            det,
            &points(&scan),
            7.0,
            null(),
            lp.as_mut_ptr(),
            &mut found,
        );
        assert_eq!(s, SolidStatus::Ok, "{}", last_error());
        solid_detector_len(det, &mut n);
        assert_eq!(n, 6);
        solid_database_len(back, &mut n);
        assert_eq!(n, 5);
        solid_detector_entry(det, 2, &mut session, &mut t, pose.as_mut_ptr());
        assert_eq!((session, t, pose[3]), (0, 2.0, 2.0));
        solid_detector_entry(det, 5, &mut session, &mut t, null_mut());
        assert_eq!((session, t), (1, 7.0));
        let (r, a) = ([1f32; 40], [1f32; 60]);
        let s = solid_database_add(
            back,
            r.as_ptr(),
            40,
            a.as_ptr(),
            60,
            0,
            8.0,
            null(),
            null_mut(),
        );
        assert_eq!(s, SolidStatus::Ok);
        solid_database_len(back, &mut n);
        assert_eq!(n, 6);
        solid_detector_len(det, &mut n);
        assert_eq!(n, 6);
        solid_detector_entry(det, 5, &mut session, &mut t, null_mut());
        assert_eq!((session, t), (1, 7.0));
        solid_detector_free(det);
        solid_detector_config_free(dc);
        solid_database_free(back);
        std::fs::write(dir.join("junk"), b"not a database").unwrap();
        let junk = c(dir.join("junk").to_str().unwrap());
        assert_eq!(
            solid_database_load(junk.as_ptr(), &mut back),
            SolidStatus::Format
        );
        assert_eq!(
            solid_database_load(c("/nonexistent/x").as_ptr(), &mut back),
            SolidStatus::Io
        );
        solid_database_free(db);
        solid_config_free(cfg);
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn detector_finds_a_verified_loop_with_its_pose() {
    let cfg = config("vlp16");
    let mut dc = null_mut();
    let mut det = null_mut();
    unsafe {
        solid_detector_config_new(c("vlp16").as_ptr(), &mut dc);
        solid_detector_config_set(dc, c("exclude_frames").as_ptr(), 2.0);
        // One revisit, no steps before it to support it, excluded by frames only (the poses
        // give a path, which the metres window would otherwise count).
        solid_detector_config_set(dc, c("exclude_meters").as_ptr(), 0.0);
        solid_detector_config_set(dc, c("min_support").as_ptr(), 0.0);
        assert_eq!(solid_detector_new(cfg, dc, &mut det), SolidStatus::Ok);
        let mut loops = Vec::new();
        // The sensor moves 3 m a step along -x, then is carried back near its start: its poses
        // (T_world_sensor, row-major 4x4) say so. Without them the detector's own odometry
        // (scan-to-scan registration) could not link the jump back, and a scan it cannot link
        // is related to no place (spec §8).
        for (k, shift) in [0.0, 3.0, 6.0, 9.0, 0.4].into_iter().enumerate() {
            let scan = room(shift);
            let pose = [
                1.0, 0.0, 0.0, -shift, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
            ];
            let mut lp = std::mem::MaybeUninit::<SolidLoop>::uninit();
            let mut found = false;
            let s = if k % 2 == 0 {
                solid_detector_add(
                    det,
                    &points(&scan),
                    k as f64,
                    pose.as_ptr(),
                    lp.as_mut_ptr(),
                    &mut found,
                )
            } else {
                let mut sc = null_mut();
                assert_eq!(
                    solid_detector_prepare(det, &points(&scan), &mut sc),
                    SolidStatus::Ok
                );
                solid_detector_add_scan(
                    det,
                    sc,
                    k as f64,
                    pose.as_ptr(),
                    lp.as_mut_ptr(),
                    &mut found,
                )
            };
            assert_eq!(s, SolidStatus::Ok, "{}", last_error());
            if found {
                loops.push(lp.assume_init());
            }
        }
        let lp = loops.last().expect("the revisit is a loop");
        assert_eq!((lp.query, lp.candidate), (4, 0));
        assert!(lp.verified);
        // The query's points lie 0.4 m further along x: p_query = p_candidate + 0.4 x.
        assert!((lp.pose[3] - 0.4).abs() < 0.05, "{:?}", lp.pose);
        // The registration's information: symmetric, every axis constrained.
        for i in 0..6 {
            assert!(lp.information[i * 6 + i] > 0.0, "{:?}", lp.information);
            for j in 0..6 {
                let (a, b) = (lp.information[i * 6 + j], lp.information[j * 6 + i]);
                assert!(
                    (a - b).abs() <= 1e-9 * a.abs().max(1.0),
                    "{:?}",
                    lp.information
                );
            }
        }
        // A scan handed back without adding it, and a NULL scan, are fine.
        let mut sc = null_mut();
        solid_detector_prepare(det, &points(&room(1.0)), &mut sc);
        solid_scan_free(sc);
        assert_eq!(
            solid_detector_add_scan(det, null_mut(), 0.0, null(), null_mut(), null_mut()),
            SolidStatus::InvalidArgument
        );
        let mut n = 0;
        solid_detector_len(det, &mut n);
        assert_eq!(n, 5);
        solid_detector_free(det);
        solid_detector_config_free(dc);
        solid_config_free(cfg);
    }
}

#[test]
fn registration_recovers_a_shift() {
    let (a, b) = (room(0.0), room(0.3));
    let (mut qa, mut qb) = (null_mut(), null_mut());
    let mut out = std::mem::MaybeUninit::<SolidRegistration>::uninit();
    unsafe {
        assert_eq!(
            solid_cloud_new(&points(&b), null(), &mut qb),
            SolidStatus::Ok
        );
        assert_eq!(
            solid_cloud_new(&points(&a), null(), &mut qa),
            SolidStatus::Ok
        );
        assert_eq!(
            solid_register(qb, qa, null(), null(), out.as_mut_ptr()),
            SolidStatus::Ok
        );
        let r = out.assume_init();
        assert!(
            (r.pose[3] - 0.3).abs() < 0.05 && r.fitness > 0.5,
            "{:?}",
            r.pose
        );
        let mut rc = null_mut();
        solid_reg_config_new(&mut rc);
        solid_reg_config_set(rc, c("voxel_size").as_ptr(), 0.25);
        // Clouds prepared with other voxel sizes are refused.
        assert_eq!(
            solid_register(qb, qa, null(), rc, out.as_mut_ptr()),
            SolidStatus::ConfigMismatch
        );
        solid_reg_config_free(rc);
        solid_cloud_free(qa);
        solid_cloud_free(qb);
    }
}

#[test]
fn errors_are_per_thread_and_free_accepts_null() {
    unsafe {
        solid_config_new(c("nope").as_ptr(), &mut null_mut());
        let here = last_error();
        let there = std::thread::spawn(last_error).join().unwrap();
        assert!(here.contains("unknown preset") && there.is_empty());
        solid_config_free(null_mut());
        solid_describer_free(null_mut());
        solid_database_free(null_mut());
        solid_detector_free(null_mut());
        solid_cloud_free(null_mut());
        solid_scan_free(null_mut());
        assert_eq!(
            CStr::from_ptr(solid_version()).to_str().unwrap(),
            env!("CARGO_PKG_VERSION")
        );
    }
}

/// Issue 39: the saves rename their temporary file into place, but never over what is not a
/// regular file (run as root, `-o /dev/null` had turned the null device into a file): a FIFO of
/// the test's own making is refused (`SOLID_STATUS_IO`, the message naming it) and stays a FIFO.
#[cfg(unix)]
#[test]
fn saves_never_replace_a_fifo() {
    use std::os::unix::fs::FileTypeExt;
    let dir = std::env::temp_dir().join(format!("solid-c-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("out");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("skipped: no mkfifo");
        return;
    }
    let path = c(fifo.to_str().unwrap());
    let cfg = config("hdl64");
    let (mut db, mut dc, mut det) = (null_mut(), null_mut(), null_mut());
    unsafe {
        assert_eq!(solid_database_new(cfg, &mut db), SolidStatus::Ok);
        assert_eq!(solid_database_save(db, path.as_ptr()), SolidStatus::Io);
        assert!(
            last_error().contains("a FIFO, not a regular file"),
            "{}",
            last_error()
        );
        solid_detector_config_new(c("hdl64").as_ptr(), &mut dc);
        assert_eq!(solid_detector_new(cfg, dc, &mut det), SolidStatus::Ok);
        assert_eq!(solid_detector_save(det, path.as_ptr()), SolidStatus::Io);
        assert!(
            last_error().contains("refusing to replace it"),
            "{}",
            last_error()
        );
        // verify_threads is bounded by the parameter table (a million threads were started).
        assert_eq!(
            solid_detector_config_set(dc, c("verify_threads").as_ptr(), 1e6),
            SolidStatus::InvalidParameter
        );
        assert!(last_error().contains("verify_threads"), "{}", last_error());
        solid_detector_free(det);
        solid_detector_config_free(dc);
        solid_database_free(db);
        solid_config_free(cfg);
    }
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(left.len(), 1, "a temporary file was left");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_loop_keeps_its_layout() {
    // SolidLoop is written into the caller's memory: a program built against an earlier header
    // must find every field where it was (new reports come in new structs and functions).
    use std::mem::{offset_of, size_of};
    assert_eq!(size_of::<SolidLoop>(), 472);
    let offsets = [
        offset_of!(SolidLoop, query),
        offset_of!(SolidLoop, candidate),
        offset_of!(SolidLoop, distance),
        offset_of!(SolidLoop, heading_deg),
        offset_of!(SolidLoop, score),
        offset_of!(SolidLoop, verified),
        offset_of!(SolidLoop, pose),
        offset_of!(SolidLoop, information),
        offset_of!(SolidLoop, fitness),
        offset_of!(SolidLoop, rmse),
    ];
    assert_eq!(offsets, [0, 4, 8, 16, 24, 32, 40, 168, 456, 464]);
}

#[test]
fn a_step_reports_its_pose_and_where_it_came_from() {
    let cfg = config("vlp16");
    let mut dc = null_mut();
    let mut det = null_mut();
    unsafe {
        solid_detector_config_new(c("vlp16").as_ptr(), &mut dc);
        assert_eq!(solid_detector_new(cfg, dc, &mut det), SolidStatus::Ok);
        let mut step = std::mem::MaybeUninit::<SolidStep>::uninit();
        assert_eq!(
            solid_detector_last_step(det, step.as_mut_ptr()),
            SolidStatus::InvalidArgument
        );
        assert!(
            last_error().contains("no scan was added yet"),
            "{}",
            last_error()
        );
        // No map: never placed, and the anchor is not written (NULL is fine).
        let mut placed = true;
        assert_eq!(
            solid_detector_map_anchor(det, null_mut(), &mut placed),
            SolidStatus::Ok
        );
        assert!(!placed);
        let add = |shift: f64, pose: Option<&[f64; 16]>| {
            let scan = room(shift);
            let p = pose.map_or(null(), |p| p.as_ptr());
            let s = solid_detector_add(det, &points(&scan), f64::NAN, p, null_mut(), null_mut());
            assert_eq!(s, SolidStatus::Ok, "{}", last_error());
            let mut step = std::mem::MaybeUninit::<SolidStep>::uninit();
            assert_eq!(
                solid_detector_last_step(det, step.as_mut_ptr()),
                SolidStatus::Ok
            );
            step.assume_init()
        };
        // Without the caller's pose the detector's own odometry starts a frame (the identity),
        // then chains each scan onto the previous one: the room's points 0.5 m further along x
        // are the sensor 0.5 m back.
        let first = add(0.0, None);
        assert_eq!(
            (
                first.query,
                first.pose_source,
                first.placement,
                first.released,
                first.deferred
            ),
            (0, SolidPoseSource::Started, SolidPlacement::None, 0, 0)
        );
        let identity = [
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        assert_eq!(first.pose, identity);
        let second = add(0.5, None);
        assert_eq!(
            (second.query, second.pose_source),
            (1, SolidPoseSource::Chained)
        );
        assert!((second.pose[3] + 0.5).abs() < 0.05, "{:?}", second.pose);
        assert!(second.pose[7].abs() < 0.05 && second.pose[11].abs() < 0.05);
        assert_eq!(second.pose[12..], [0.0, 0.0, 0.0, 1.0]);
        // A given pose is the step's, as given.
        let mut given = identity;
        given[3] = 7.0;
        let third = add(1.0, Some(&given));
        assert_eq!(
            (third.pose_source, third.pose),
            (SolidPoseSource::Given, given)
        );
        // No loop was held, so none was released: an empty buffer is enough.
        let mut n = 99;
        assert_eq!(
            solid_detector_released(det, null_mut(), 0, &mut n),
            SolidStatus::Ok
        );
        assert_eq!(n, 0);
        assert_eq!(
            solid_detector_released(det, null_mut(), 0, null_mut()),
            SolidStatus::InvalidArgument
        );
        solid_detector_free(det);
        solid_detector_config_free(dc);
        solid_config_free(cfg);
    }
}
