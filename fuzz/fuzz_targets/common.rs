//! What the fuzz targets share: reading fixed-size fields from the input.

/// The next `N` bytes of `d` (zeros past its end), advancing it.
pub fn take<const N: usize>(d: &mut &[u8]) -> [u8; N] {
    let mut v = [0u8; N];
    let n = d.len().min(N);
    v[..n].copy_from_slice(&d[..n]);
    *d = &d[n..];
    v
}
