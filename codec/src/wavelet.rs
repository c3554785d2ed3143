//! Lifting wavelet transforms (placeholder signatures; being implemented).

/// Which wavelet a stream uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Wavelet {
    /// CDF 9/7 biorthogonal, floating point, lossy.
    Cdf97,
    /// Reversible integer 5/3 (LeGall), lossless.
    Int53,
}

/// Orientation of a subband.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Orientation {
    /// Low-pass in both directions (only at the coarsest level).
    LL,
    /// High-pass horizontally (vertical edges), right of LL.
    HL,
    /// High-pass vertically (horizontal edges), below LL.
    LH,
    /// High-pass in both directions.
    HH,
}

/// One subband's rectangle inside the transformed buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Subband {
    /// Decomposition level, 1 = finest, `levels` = coarsest.
    pub level: u32,
    /// Orientation.
    pub orientation: Orientation,
    /// Left column of the subband in the buffer.
    pub x0: usize,
    /// Top row of the subband in the buffer.
    pub y0: usize,
    /// Columns (may be 0).
    pub width: usize,
    /// Rows (may be 0).
    pub height: usize,
}

/// Default number of levels.
pub fn default_levels(_width: usize, _height: usize) -> u32 {
    todo!()
}

/// Subbands ordered coarse to fine.
pub fn subbands(_width: usize, _height: usize, _levels: u32) -> Vec<Subband> {
    todo!()
}

/// Forward integer 5/3.
pub fn forward_53(_data: &mut [i32], _width: usize, _height: usize, _levels: u32) {
    todo!()
}

/// Inverse integer 5/3.
pub fn inverse_53(_data: &mut [i32], _width: usize, _height: usize, _levels: u32) {
    todo!()
}

/// Forward CDF 9/7.
pub fn forward_97(_data: &mut [f32], _width: usize, _height: usize, _levels: u32) {
    todo!()
}

/// Inverse CDF 9/7.
pub fn inverse_97(_data: &mut [f32], _width: usize, _height: usize, _levels: u32) {
    todo!()
}

/// Synthesis L2 norms per subband, in `subbands()` order.
pub fn synthesis_norms(_wavelet: Wavelet, _width: usize, _height: usize, _levels: u32) -> Vec<f64> {
    todo!()
}
