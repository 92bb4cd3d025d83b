//! World parameters, checked once where they enter; core code trusts them.

/// The widest field of view: a window row then fits a few machine words and the per-map
/// visibility table stays small.
pub const MAX_FOV: usize = 255;

/// The paper's values: L = 25, D = 1, Rmax = 400.
pub const PAPER_FOV: usize = 25;
pub const PAPER_DECAY: f32 = 1.0;
pub const PAPER_RMAX: f32 = 400.0;

/// Field of view L (odd: the square is centred on a cell), decay D and floor Rmax.
///
/// Penalties are `f32`; with integer D and Rmax every penalty is an integer and exact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldParams {
    fov: usize,
    decay: f32,
    rmax: f32,
}

impl WorldParams {
    pub fn new(fov: usize, decay: f32, rmax: f32) -> Result<Self, ParamError> {
        if fov.is_multiple_of(2) || fov > MAX_FOV {
            return Err(ParamError::Fov(fov));
        }
        if !decay.is_finite() || decay < 0.0 {
            return Err(ParamError::Decay(decay));
        }
        if !rmax.is_finite() || rmax <= 0.0 {
            return Err(ParamError::Rmax(rmax));
        }
        Ok(Self { fov, decay, rmax })
    }

    pub fn paper() -> Self {
        Self {
            fov: PAPER_FOV,
            decay: PAPER_DECAY,
            rmax: PAPER_RMAX,
        }
    }

    /// Side L of the square field of view.
    pub fn fov(&self) -> usize {
        self.fov
    }

    /// Cells from the agent to the edge of its field of view: (L - 1) / 2.
    pub(crate) fn half_fov(&self) -> usize {
        self.fov / 2
    }

    pub fn decay(&self) -> f32 {
        self.decay
    }

    pub fn rmax(&self) -> f32 {
        self.rmax
    }
}

/// World parameters that make no sense, named by field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("fov (L) must be odd and between 1 and {max}, got {0}", max = MAX_FOV)]
    Fov(usize),
    #[error("decay (D) must be finite and >= 0, got {0}")]
    Decay(f32),
    #[error("rmax must be finite and > 0, got {0}")]
    Rmax(f32),
    #[error("a link radius must be finite and >= 0, got {0}")]
    LinkRadius(f64),
    #[error("a link's drop probability must be between 0 and 1, got {0}")]
    LinkDrop(f64),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_impossible_values() {
        assert_eq!(WorldParams::new(24, 1.0, 400.0), Err(ParamError::Fov(24)));
        assert_eq!(WorldParams::new(0, 1.0, 400.0), Err(ParamError::Fov(0)));
        assert_eq!(WorldParams::new(257, 1.0, 400.0), Err(ParamError::Fov(257)));
        assert_eq!(
            WorldParams::new(25, -1.0, 400.0),
            Err(ParamError::Decay(-1.0))
        );
        assert!(matches!(
            WorldParams::new(25, 1.0, f32::NAN),
            Err(ParamError::Rmax(_))
        ));
        assert_eq!(WorldParams::new(25, 1.0, 400.0), Ok(WorldParams::paper()));
    }
}
