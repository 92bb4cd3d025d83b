//! The float a product runs on: its arithmetic, the lanes of a dot product, a tile kernel and
//! per-thread packing buffers, for `f32` (training) and `f64` (gradient checks). A leaf below
//! the products (`packed`, the dot products in `mod.rs`), which all need it.

use std::cell::RefCell;

use super::kernel::TileKernel;
use super::lanes::{LANES, LaneSums};

/// What the products need of a float: its arithmetic, the lanes of a dot product, a tile
/// kernel and packing buffers. The layers' float (`real::Real`) extends it.
pub trait Scalar:
    num_traits::Float
    + ndarray::LinalgScalar
    + std::ops::AddAssign
    + std::fmt::Debug
    + Default
    + Send
    + Sync
    + TileKernel
    + PackingBuffers
    + 'static
{
    /// Partial sums of a dot product, one per lane.
    type Lanes: LaneSums<Self>;
}

impl Scalar for f32 {
    /// One AVX2 register.
    type Lanes = wide::f32x8;
}

impl Scalar for f64 {
    type Lanes = [f64; LANES];
}

/// Per-thread packing buffers of one float type, which grow to the largest block and are
/// then reused, so a product allocates nothing once warm.
pub trait PackingBuffers: Sized {
    fn with_packing_buffers(f: impl FnOnce(&mut Vec<Self>, &mut Vec<Self>));
}

macro_rules! packing_buffers {
    ($t:ty) => {
        impl PackingBuffers for $t {
            fn with_packing_buffers(f: impl FnOnce(&mut Vec<Self>, &mut Vec<Self>)) {
                thread_local! {
                    static BUFFERS: RefCell<(Vec<$t>, Vec<$t>)> = const {
                        RefCell::new((Vec::new(), Vec::new()))
                    };
                }
                BUFFERS.with_borrow_mut(|(a, b)| f(a, b));
            }
        }
    };
}

packing_buffers!(f32);
packing_buffers!(f64);
