//! Finding a chessboard's inner corners in an image: the grey image they work on, the whole
//! board found and ordered ([`find`]), the detector's grid fitted to the board ([`grid`]) and the sub-pixel refinement ([`refine`]).

pub mod find;
mod grid;
pub mod refine;

pub use find::{Miss, find_board};
pub use refine::{Refined, refine, refine_all, verify};

/// A grey image as the corner finder reads it: grey levels 0..=255 as `f32`, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Luma {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl Luma {
    /// An 8-bit image (`data.len()` must be `width · height`).
    pub fn from_u8(width: usize, height: usize, data: &[u8]) -> Luma {
        debug_assert_eq!(data.len(), width * height);
        Luma {
            width,
            height,
            data: data.iter().map(|&v| f32::from(v)).collect(),
        }
    }

    /// A 16-bit image as the decoder gives it (grey levels scaled by 257).
    pub fn from_u16(width: usize, height: usize, data: &[u16]) -> Luma {
        debug_assert_eq!(data.len(), width * height);
        Luma {
            width,
            height,
            data: data.iter().map(|&v| f32::from(v) / 257.0).collect(),
        }
    }
}

#[cfg(test)]
mod tests;
