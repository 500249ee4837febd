//! A rendered image: linear RGB plus optional AOV layers.

/// Linear float image, row-major, row 0 at the top.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB radiance.
    pub rgb: Vec<[f32; 3]>,
    /// Optional auxiliary layers.
    pub aov: Option<Aovs>,
}

/// Auxiliary output variables, averaged over each pixel's samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    /// Albedo of the first surface hit (0 for background).
    pub albedo: Vec<[f32; 3]>,
    /// World-space outward unit normal of the first hit (0 for background).
    pub normal: Vec<[f32; 3]>,
    /// Distance from the camera to the first hit (0 for background).
    pub depth: Vec<f32>,
}

impl Image {
    /// The pixel at column `x`, row `y`.
    pub fn pixel(&self, x: u32, y: u32) -> [f32; 3] {
        self.rgb[(y * self.width + x) as usize]
    }
}
