//! Helpers of the search tests: every method over the same rows, and seeded data sets.

use solid_lidar::search::{
    brute_force, inverse_norm, normalize_rows, online_extend, online_insert, online_rebuild,
    sketch_encode, sketch_len, Cost, Exclude, Index, KdTree, Neighbor, OnlineIndex, Plan, Request,
    Rows, Sketch, SKETCH_BLOCK,
};
use solid_lidar::Error;

pub fn normed(raw: &[f32], dim: usize) -> Vec<f32> {
    let mut out = vec![0.0; raw.len()];
    normalize_rows(raw, dim, &mut out).unwrap();
    out
}

pub fn scales(raw: &[f32], dim: usize) -> Vec<f32> {
    raw.chunks_exact(dim)
        .map(|r| inverse_norm(r).unwrap())
        .collect()
}

/// The neighbours a search writes into a buffer of `k`.
fn knn(k: usize, search: impl FnOnce(&mut [Neighbor]) -> Result<usize, Error>) -> Vec<Neighbor> {
    let mut out = vec![Neighbor::default(); k];
    let n = search(&mut out).unwrap();
    out.truncate(n);
    out
}

pub fn brute(rows: Rows<'_>, q: &[f32], k: usize, ex: &Exclude<'_>) -> Vec<Neighbor> {
    knn(k, |out| brute_force(rows, q, k, ex, out))
}

pub fn tree(rows: Rows<'_>, q: &[f32], k: usize, ex: &Exclude<'_>) -> Vec<Neighbor> {
    let n = rows.len();
    let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
    let t = KdTree::build(rows, &mut perm, &mut splits).unwrap();
    let out = knn(k, |out| t.search(q, k, ex, out));
    // The built permutation is a permutation of 0..n.
    let mut sorted = perm.clone();
    sorted.sort_unstable();
    assert!(sorted.iter().enumerate().all(|(i, &p)| p as usize == i));
    out
}

/// The online index grown one row at a time.
pub fn online(rows: Rows<'_>, q: &[f32], k: usize, ex: &Exclude<'_>) -> Vec<Neighbor> {
    let n = rows.len();
    let (mut perm, mut splits) = (Vec::new(), Vec::new());
    for i in 0..n {
        perm.push(i as u32);
        splits.push(0);
        online_insert(rows.prefix(i + 1), &mut perm, &mut splits).unwrap();
    }
    let index = OnlineIndex::new(rows, &perm, &splits).unwrap();
    let out = knn(k, |out| index.search(q, k, ex, out));
    // Rebuilding from scratch, or extending from a third of the rows, gives the same structure.
    let (mut p2, mut s2) = (vec![0u32; n], vec![0u16; n]);
    online_rebuild(rows, &mut p2, &mut s2).unwrap();
    assert_eq!(p2, perm);
    let (mut p3, mut s3) = (vec![0u32; n], vec![0u16; n]);
    online_rebuild(rows.prefix(n / 3), &mut p3, &mut s3).unwrap();
    online_extend(rows, n / 3, &mut p3, &mut s3).unwrap();
    assert_eq!(p3, perm);
    out
}

/// The sketch of `rows`, encoded in two steps (as a growing database would) when there are
/// at least two rows.
pub fn sketch_of(rows: Rows<'_>) -> (Vec<u8>, Vec<f32>) {
    let n = rows.len();
    let (nc, np) = sketch_len(n, rows.dim());
    let (mut codes, mut params) = (vec![7u8; nc], vec![f32::NAN; np]);
    let half = n / 2;
    sketch_encode(rows.prefix(half), 0, &mut codes, &mut params).unwrap();
    sketch_encode(rows, half, &mut codes, &mut params).unwrap();
    (codes, params)
}

/// The online kd-tree and the sketch of every row, owned, for [`Index::new`].
pub struct Built {
    perm: Vec<u32>,
    splits: Vec<u16>,
    codes: Vec<u8>,
    params: Vec<f32>,
}

impl Built {
    pub fn of(rows: Rows<'_>) -> Built {
        let n = rows.len();
        let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
        online_rebuild(rows, &mut perm, &mut splits).unwrap();
        let (codes, params) = sketch_of(rows);
        Built {
            perm,
            splits,
            codes,
            params,
        }
    }

    pub fn index<'a>(&'a self, rows: Rows<'a>) -> Index<'a> {
        Index::new(rows, &self.perm, &self.splits, &self.codes, &self.params).unwrap()
    }
}

pub fn sketch(rows: Rows<'_>, q: &[f32], k: usize, ex: &Exclude<'_>) -> Vec<Neighbor> {
    let (codes, params) = sketch_of(rows);
    let sketch = Sketch::new(rows, &codes, &params).unwrap();
    knn(k, |out| sketch.search(q, k, ex, out))
}

/// Every plan of the index, with and without a distance bound, against brute force cut at the
/// bound, with the kd-tree over all rows and over a prefix only, and the sketch over all rows,
/// over the whole blocks of the first third and over none (a database after a bulk add);
/// returns the work of the automatic plan without a bound.
pub fn check_index(rows: Rows<'_>, q: &[f32], k: usize, ex: &Exclude<'_>) -> Cost {
    let n = rows.len();
    let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
    online_rebuild(rows, &mut perm, &mut splits).unwrap();
    let (mut pperm, mut psplits) = (vec![0u32; n / 2], vec![0u16; n / 2]);
    online_rebuild(rows.prefix(n / 2), &mut pperm, &mut psplits).unwrap();
    let (codes, params) = sketch_of(rows);
    let full = Index::new(rows, &perm, &splits, &codes, &params).unwrap();
    let part = Index::new(rows, &pperm, &psplits, &codes, &params).unwrap();
    let (sc, sp) = sketch_len(n / 3 / SKETCH_BLOCK * SKETCH_BLOCK, rows.dim());
    let part_sketch = Index::new(rows, &pperm, &psplits, &codes[..sc], &params[..sp]).unwrap();
    let no_sketch = Index::new(rows, &perm, &splits, &[], &[]).unwrap();
    let b = brute(rows, q, k, ex);
    let mut auto_cost = Cost::default();
    let mut bounds = vec![f32::INFINITY, 1.0, 0.0];
    bounds.extend(b.iter().map(|nb| nb.distance));
    bounds.extend(b.iter().map(|nb| nb.distance - 1e-7));
    // Each bound once: rows that repeat (thousands of copies of a few vectors) give the same
    // distance thousands of times, and the same search again checks nothing new.
    bounds.sort_by(|x, y| y.total_cmp(x));
    bounds.dedup();
    for (i, &max_distance) in bounds.iter().enumerate() {
        let want: Vec<Neighbor> = b
            .iter()
            .copied()
            .filter(|nb| nb.distance <= max_distance)
            .collect();
        for plan in [Plan::Brute, Plan::KdTree, Plan::Sketch, Plan::Auto] {
            let req = Request {
                k,
                exclude: *ex,
                max_distance,
                plan,
                observed: None,
            };
            for (index, which) in [
                (&full, "full tree"),
                (&part, "tree over half"),
                (&part_sketch, "tree over half, sketch over a third"),
                (&no_sketch, "full tree, no sketch"),
            ] {
                let mut out = vec![Neighbor::default(); k + 1];
                let found = index.search(q, &req, &mut out).unwrap();
                assert_eq!(
                    &out[..found.len],
                    &want[..],
                    "{plan:?} ({which}) with max_distance {max_distance}"
                );
                if plan == Plan::Auto && i == 0 && which == "full tree" {
                    auto_cost = found.cost;
                }
            }
        }
    }
    auto_cost
}

/// A seeded generator for the larger data sets below (splitmix64).
pub struct Rng(pub u64);

impl Rng {
    pub fn unit(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// `n` rows of `dim` values: copies of `places` random non-negative vectors, each value scaled by
/// up to `1 ± noise`.
pub fn places(n: usize, dim: usize, places: usize, noise: f32, rng: &mut Rng) -> Vec<f32> {
    let base: Vec<f32> = (0..places * dim).map(|_| rng.unit()).collect();
    let mut raw = Vec::with_capacity(n * dim);
    for i in 0..n {
        let p = (i * 7919) % places;
        for d in 0..dim {
            raw.push(base[p * dim + d] * (1.0 + noise * (2.0 * rng.unit() - 1.0)));
        }
    }
    normed(&raw, dim)
}
