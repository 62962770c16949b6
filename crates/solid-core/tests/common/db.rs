//! Helpers of the database tests: a config, descriptor-shaped vectors and sample databases.

use solid_lidar::db::{Database, DbError, DetectorConfig};
use solid_lidar::{Config, Descriptor, Stats};

pub fn cfg() -> Config {
    Config::preset("hdl64").unwrap()
}

pub fn desc(cfg: &Config, seed: u32) -> Descriptor {
    // A deterministic, descriptor-shaped vector pair.
    let mut x = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        (x % 1000) as f32 / 10.0
    };
    Descriptor {
        r: (0..cfg.n_range).map(|_| next()).collect(),
        a: (0..cfg.n_azimuth).map(|_| next()).collect(),
        stats: Stats::default(),
        fingerprint: cfg.fingerprint(),
    }
}

pub fn sample_db(n: u32) -> Database {
    let c = cfg();
    let mut db = Database::new(c).unwrap();
    for i in 0..n {
        let pose = (i % 2 == 0).then(|| {
            let mut p = [0.0; 12];
            p[0] = 1.0;
            p[5] = 1.0;
            p[10] = 1.0;
            p[3] = f64::from(i);
            p
        });
        let t = if i % 3 == 0 {
            f64::NAN
        } else {
            f64::from(i) * 0.1
        };
        assert_eq!(db.add(&desc(&c, i), i % 4, t, pose).unwrap(), i);
    }
    db
}

pub fn same(a: &Database, b: &Database) {
    assert_eq!(a.len(), b.len());
    assert_eq!(a.config(), b.config());
    assert_eq!(a.r_all(), b.r_all());
    assert_eq!(a.a_all(), b.a_all());
    assert_eq!(a.sessions(), b.sessions());
    same_poses(a, b);
    let bits = |d: &Database| {
        d.timestamps()
            .iter()
            .map(|t| t.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(a), bits(b));
}

/// The same places have poses, each entry within 1e-12 (a file stores a rotation as a
/// quaternion, docs/spec.md §13).
pub fn same_poses(a: &Database, b: &Database) {
    assert_eq!(a.len(), b.len());
    for id in 0..a.len() as u32 {
        match (a.pose(id), b.pose(id)) {
            (None, None) => {}
            (Some(p), Some(q)) => {
                let far = p
                    .iter()
                    .zip(&q)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                assert!(far <= 1e-12, "place {id}: pose moved by {far}");
            }
            (p, q) => panic!("place {id}: pose {p:?} became {q:?}"),
        }
    }
}

pub fn format_reason(e: DbError) -> String {
    match e {
        DbError::Format { reason, .. } => reason,
        other => panic!("expected a format error, got {other:?}"),
    }
}

/// The vectors, sessions, timestamps and poses of `sample_db(n)`, as arrays for a batch add.
#[allow(clippy::type_complexity)]
pub fn sample_arrays(n: u32) -> (Vec<f32>, Vec<f32>, Vec<f64>, Vec<[f64; 12]>) {
    let c = cfg();
    let (mut r, mut a, mut t, mut p) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let d = desc(&c, i);
        r.extend_from_slice(&d.r);
        a.extend_from_slice(&d.a);
        t.push(f64::from(i) * 0.5);
        let mut pose = [0.0; 12];
        (pose[0], pose[5], pose[10], pose[3]) = (1.0, 1.0, 1.0, f64::from(i));
        p.push(pose);
    }
    (r, a, t, p)
}

/// The detector defaults without verification (these tests feed descriptors, not points).
pub fn unverified() -> DetectorConfig {
    let mut c = DetectorConfig::default();
    c.verify.enabled = false;
    c
}

/// Writes `to`: the file `from` (a saved `db`) with one byte flipped in the middle of place
/// `id`'s stored cloud, so that the file loads and that cloud fails its checksum.
#[cfg(feature = "std")]
pub fn flip_cloud_byte(db: &Database, id: u32, from: &std::path::Path, to: &std::path::Path) {
    let mut raw = std::fs::read(from).unwrap();
    let cloud = db.cloud(id).unwrap().unwrap().into_owned();
    let at = raw.windows(cloud.len()).position(|w| w == cloud).unwrap();
    raw[at + cloud.len() / 2] ^= 0xFF;
    std::fs::write(to, &raw).unwrap();
}
