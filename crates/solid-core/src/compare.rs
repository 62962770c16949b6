//! Comparing descriptors ([spec §3](crate::spec#3-comparing-descriptors)): cosine distance of R-SOLiDs and heading from A-SOLiDs.

use crate::angle::wrap180;
use crate::math::sqrt;
use crate::Error;

fn same_len(what: &'static str, a: &[f32], b: &[f32]) -> Result<(), Error> {
    if a.len() != b.len() {
        return Err(Error::LengthMismatch {
            what,
            left: a.len(),
            right: b.len(),
        });
    }
    if a.is_empty() {
        return Err(Error::Empty { what });
    }
    Ok(())
}

/// Cosine distance `1 − q·c / (‖q‖‖c‖)` between two R-SOLiDs, in `[0, 1]` for the non-negative
/// vectors SOLiD produces; `1` when either vector is all zeros ([spec §3](crate::spec#3-comparing-descriptors)). Accumulates in `f64`.
///
/// # Errors
/// [`Error::LengthMismatch`] when the lengths differ, [`Error::Empty`] when both are empty.
pub fn cosine_distance(q: &[f32], c: &[f32]) -> Result<f64, Error> {
    same_len("r_solid", q, c)?;
    let (mut dot, mut nq, mut nc) = (0.0f64, 0.0f64, 0.0f64);
    for (&a, &b) in q.iter().zip(c) {
        let (a, b) = (f64::from(a), f64::from(b));
        dot += a * b;
        nq += a * a;
        nc += b * b;
    }
    if nq == 0.0 || nc == 0.0 {
        return Ok(1.0);
    }
    // One square root of the product: identical vectors give exactly 0 (f32 inputs cannot overflow it).
    let d = 1.0 - dot / sqrt(nq * nc);
    Ok(d.clamp(0.0, 1.0))
}

/// A heading estimate between two scans ([spec §3](crate::spec#3-comparing-descriptors)): the query ≈ the candidate rotated by
/// `degrees` about +z (counter-clockwise seen from above).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heading {
    /// The best circular shift `s*` of the candidate's A-SOLiD, in bins (`0..n_azimuth`).
    pub shift: usize,
    /// The heading in degrees, wrapped into `(−180, 180]`.
    pub degrees: f64,
}

/// `Σⱼ f(q[j], c[(j − s) mod n])` in `f64`: the crate's one circular-shift kernel (shift costs,
/// aligned correlations). `q` and `c` have the same length `n` and `s < n`.
#[inline]
pub(crate) fn circular_sum(q: &[f32], c: &[f32], s: usize, f: impl Fn(f64, f64) -> f64) -> f64 {
    let n = q.len();
    // j in s..n reads c[j - s]; j in 0..s reads c[j + n - s].
    let head: f64 = q[s..]
        .iter()
        .zip(&c[..n - s])
        .map(|(&a, &b)| f(f64::from(a), f64::from(b)))
        .sum();
    let tail: f64 = q[..s]
        .iter()
        .zip(&c[n - s..])
        .map(|(&a, &b)| f(f64::from(a), f64::from(b)))
        .sum();
    head + tail
}

/// `cost[s] = Σⱼ (q[j] − c[(j − s) mod n])²` ([spec §3](crate::spec#3-comparing-descriptors)).
fn shift_cost(q: &[f32], c: &[f32], s: usize) -> f64 {
    circular_sum(q, c, s, |a, b| (a - b) * (a - b))
}

/// Cosine distance between `q` and `c` circularly shifted by the shift that aligns them best
/// (the largest correlation `Σⱼ q[j]·c[(j − s) mod n]` over all shifts), in `[0, 1]`; 1 when
/// either vector is all zero. The loop detector re-ranks candidates with it.
///
/// # Errors
/// [`Error::LengthMismatch`] when the lengths differ, [`Error::Empty`] when both are empty.
pub fn aligned_distance(q: &[f32], c: &[f32]) -> Result<f64, Error> {
    same_len("a_solid", q, c)?;
    let norm2 = |v: &[f32]| -> f64 { v.iter().map(|&x| f64::from(x) * f64::from(x)).sum() };
    let (nq, nc) = (norm2(q), norm2(c));
    if nq == 0.0 || nc == 0.0 {
        return Ok(1.0);
    }
    let best = (0..q.len())
        .map(|s| circular_sum(q, c, s, |a, b| a * b))
        .fold(f64::NEG_INFINITY, f64::max);
    Ok((1.0 - best / sqrt(nq * nc)).clamp(0.0, 1.0))
}

fn best_shift(q: &[f32], c: &[f32]) -> (usize, f64) {
    let mut best = (0, shift_cost(q, c, 0));
    for s in 1..q.len() {
        let cost = shift_cost(q, c, s);
        if cost < best.1 {
            best = (s, cost);
        }
    }
    best
}

/// Integer heading ([spec §3](crate::spec#3-comparing-descriptors)): the first shift that minimises the squared difference of the
/// A-SOLiDs, as `s*·360/n` degrees wrapped into `(−180, 180]`.
///
/// # Errors
/// [`Error::LengthMismatch`] when the lengths differ, [`Error::Empty`] when both are empty.
pub fn heading(a_query: &[f32], a_candidate: &[f32]) -> Result<Heading, Error> {
    same_len("a_solid", a_query, a_candidate)?;
    let (s, _) = best_shift(a_query, a_candidate);
    Ok(Heading {
        shift: s,
        degrees: wrap180(s as f64 * 360.0 / a_query.len() as f64),
    })
}

/// Refined heading ([spec §3](crate::spec#3-comparing-descriptors)): the integer heading plus a parabolic sub-bin offset
/// `δ = (c₋ − c₊) / (2(c₋ − 2c₀ + c₊))` in `[−0.5, 0.5]` (0 when the parabola is not convex).
///
/// # Errors
/// [`Error::LengthMismatch`] when the lengths differ, [`Error::Empty`] when both are empty.
pub fn heading_refined(a_query: &[f32], a_candidate: &[f32]) -> Result<Heading, Error> {
    same_len("a_solid", a_query, a_candidate)?;
    let n = a_query.len();
    let (s, c0) = best_shift(a_query, a_candidate);
    let cm = shift_cost(a_query, a_candidate, (s + n - 1) % n);
    let cp = shift_cost(a_query, a_candidate, (s + 1) % n);
    Ok(refined(s, n, [cm, c0, cp]))
}

/// The heading at shift `s` of `n` refined by the parabola through the costs `[c₋, c₀, c₊]` at
/// `s − 1, s, s + 1` (SPEC §3).
fn refined(s: usize, n: usize, [cm, c0, cp]: [f64; 3]) -> Heading {
    let den = 2.0 * (cm - 2.0 * c0 + cp);
    let delta = if den > 0.0 {
        ((cm - cp) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    Heading {
        shift: s,
        degrees: wrap180((s as f64 + delta) * 360.0 / n as f64),
    }
}

/// The local minima of the SPEC §3 shift cost, lowest cost first (ties by lower shift), each
/// refined as in [`heading_refined`]: up to `out.len()` of them are written to `out`, and their
/// number is returned. These are the initial yaws worth trying when the heading is ambiguous
/// (a narrow field of view, a symmetric place): the first is [`heading_refined`]'s answer.
///
/// A shift is a local minimum when its cost is below its left neighbour's and not above its
/// right neighbour's (circularly), so a flat valley counts once, at its first shift; SPEC's
/// `s*` always counts (a cost that is flat everywhere, from all-zero vectors, has that one
/// minimum, shift 0). Allocates nothing.
///
/// # Errors
/// [`Error::LengthMismatch`] when the lengths differ, [`Error::Empty`] when both are empty.
pub fn heading_minima(
    a_query: &[f32],
    a_candidate: &[f32],
    out: &mut [Heading],
) -> Result<usize, Error> {
    same_len("a_solid", a_query, a_candidate)?;
    if out.is_empty() {
        return Ok(0);
    }
    let n = a_query.len();
    let cost = |s: usize| shift_cost(a_query, a_candidate, s % n);
    // Kept sorted by (cost, shift): a bounded insertion into `out` alongside their costs.
    let mut costs = [0.0f64; MAX_MINIMA];
    let cap = out.len().min(MAX_MINIMA);
    let mut m = 0;
    let (s_star, c_star) = best_shift(a_query, a_candidate);
    let (c_first, c_second) = (cost(0), cost(1));
    let mut window = [cost(n - 1), c_first, c_second];
    for s in 0..n {
        if s > 0 {
            let next = if s + 1 == n { c_first } else { cost(s + 1) };
            window = [window[1], window[2], next];
        }
        let [cm, c0, cp] = window;
        // SPEC's s* always counts; another shift of exactly its cost never does, so that s*
        // comes first even when its valley wraps around shift 0.
        let is_min = s == s_star || (c0 < cm && c0 <= cp && c0 != c_star);
        if !is_min {
            continue;
        }
        let mut at = m;
        while at > 0 && costs[at - 1] > c0 {
            at -= 1;
        }
        if at >= cap {
            continue;
        }
        let end = m.min(cap - 1);
        for k in (at..end).rev() {
            costs[k + 1] = costs[k];
            out[k + 1] = out[k];
        }
        costs[at] = c0;
        out[at] = refined(s, n, window);
        m = (m + 1).min(cap);
    }
    Ok(m)
}

/// Most minima [`heading_minima`] returns (their costs are kept on the stack).
pub const MAX_MINIMA: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_basics() {
        assert!(cosine_distance(&[1.0, 2.0], &[2.0, 4.0]).unwrap() < 1e-15);
        assert_eq!(
            cosine_distance(&[1.5, 2.0, 7.0], &[1.5, 2.0, 7.0]).unwrap(),
            0.0
        );
        assert_eq!(cosine_distance(&[1.0, 0.0], &[0.0, 3.0]).unwrap(), 1.0);
        assert_eq!(cosine_distance(&[0.0, 0.0], &[0.0, 0.0]).unwrap(), 1.0);
        assert_eq!(cosine_distance(&[0.0, 0.0], &[1.0, 0.0]).unwrap(), 1.0);
        let d = cosine_distance(&[1.0, 1.0], &[1.0, 0.0]).unwrap();
        assert!((d - (1.0 - core::f64::consts::FRAC_1_SQRT_2)).abs() < 1e-12);
        assert!(matches!(
            cosine_distance(&[1.0], &[1.0, 2.0]),
            Err(Error::LengthMismatch { .. })
        ));
        assert!(matches!(
            cosine_distance(&[], &[]),
            Err(Error::Empty { .. })
        ));
    }

    fn bump(n: usize, at: f64) -> [f32; 60] {
        let mut v = [0.0f32; 60];
        for (j, x) in v.iter_mut().enumerate().take(n) {
            let d = (j as f64 - at).rem_euclid(n as f64);
            let d = d.min(n as f64 - d);
            *x = (10.0 * libm::exp(-d * d / 8.0)) as f32;
        }
        v
    }

    #[test]
    fn heading_sign_follows_the_convention() {
        // Query = candidate rotated by +30° (5 bins of 6°): features move to higher azimuth.
        let c = bump(60, 10.0);
        let q = bump(60, 15.0);
        let h = heading(&q, &c).unwrap();
        assert_eq!((h.shift, h.degrees), (5, 30.0));
        let h = heading(&c, &q).unwrap();
        assert_eq!((h.shift, h.degrees), (55, -30.0));
        // Exactly half a turn stays +180.
        let q = bump(60, 40.0);
        assert_eq!(heading(&q, &c).unwrap().degrees, 180.0);
    }

    #[test]
    fn minima_are_sorted_local_minima_and_start_with_the_heading() {
        // Two bumps in the query (at bins 15 and 40), one in the candidate (bin 10): shifts 5
        // and 30 align one bump each; the larger query bump gives the lower cost.
        let c = bump(60, 10.0);
        let mut q = bump(60, 15.0);
        for (x, y) in q.iter_mut().zip(bump(60, 40.0)) {
            *x += 0.6 * y;
        }
        let mut out = [Heading {
            shift: 0,
            degrees: 0.0,
        }; 4];
        let m = heading_minima(&q, &c, &mut out).unwrap();
        assert!(m >= 2, "{m}");
        assert_eq!((out[0].shift, out[1].shift), (5, 30));
        assert_eq!(out[0], heading_refined(&q, &c).unwrap());
        let cost = |s: usize| shift_cost(&q, &c, s % 60);
        for h in &out[..m] {
            let s = h.shift;
            assert!(cost(s) < cost(s + 59) && cost(s) <= cost(s + 1));
        }
        for w in out[..m].windows(2) {
            assert!(cost(w[0].shift) <= cost(w[1].shift));
        }
        // Capacity 1 keeps the best; a flat cost gives shift 0; no room gives nothing.
        let mut one = [out[0]; 1];
        assert_eq!(heading_minima(&q, &c, &mut one).unwrap(), 1);
        assert_eq!(one[0].shift, 5);
        let z = [0.0f32; 60];
        assert_eq!(heading_minima(&z, &z, &mut one).unwrap(), 1);
        assert_eq!((one[0].shift, one[0].degrees), (0, 0.0));
        assert_eq!(heading_minima(&q, &c, &mut []).unwrap(), 0);
        assert!(heading_minima(&q, &c[..59], &mut one).is_err());
        // Tiny vectors (n = 1, 2) work.
        assert_eq!(heading_minima(&[1.0], &[2.0], &mut out).unwrap(), 1);
        assert!(heading_minima(&[1.0, 0.0], &[0.0, 1.0], &mut out).unwrap() >= 1);
    }

    #[test]
    fn refined_heading_interpolates_between_bins() {
        let c = bump(60, 10.0);
        let q = bump(60, 12.5); // +15°
        let h = heading_refined(&q, &c).unwrap();
        assert!((h.degrees - 15.0).abs() < 1.0, "{}", h.degrees);
        // A flat cost (all-zero vectors) gives shift 0, no refinement.
        let z = [0.0f32; 60];
        assert_eq!(heading_refined(&z, &z).unwrap().degrees, 0.0);
    }
}
