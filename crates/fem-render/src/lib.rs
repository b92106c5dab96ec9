//! Pictures of 2D finite-element runs, kept out of the simulation crates so that users who only
//! simulate do not pay for them:
//!
//! - [`frame`]: the deformed mesh coloured by a per-element or per-vertex field (von Mises,
//!   displacement magnitude, det F) with a perceptual colormap, a colorbar with units and range,
//!   a title, obstacles, an optional wireframe and rest-shape outline; several panels side by
//!   side share one colorbar. Encoded to PNG by [`Image::to_png`].
//! - [`gif`]: animated GIFs from a sequence of frames.
//! - [`chart`]: line charts (probe curves) and grid charts (stability maps) as SVG, and as PNG
//!   through the same SVG.
//! - [`pressure`]: a contact pressure along the body's boundary, a coloured thick line with a
//!   legend, drawn over a frame.
//! - [`vtk`]: `.vtu` files per frame and a `.pvd` collection for ParaView, and a small reader.
//!
//! The crate depends on no other workspace crate: a mesh is a slice of positions and a slice of
//! triangles. Text uses DejaVu Sans, carried in `assets/` (Bitstream Vera licence), so pictures
//! look the same on a fresh machine with no fonts installed.

pub mod chart;
pub mod colormap;
mod error;
pub use error::write_atomic;
pub mod frame;
pub mod gif;
mod image;
pub mod pressure;
mod raster;
pub mod surface;
mod text;
pub mod vtk;

pub use error::{RenderError, Result};
pub use image::{Image, Rgba};

pub use colormap::Colormap;
pub use frame::{FieldValues, FlatElements, FrameStyle, MeshView, Rendered};
pub use gif::GifWriter;

/// The types most programs need, in one import: `use fem_render::prelude::*;`.
///
/// Frames ([`render`](frame::render) and its inputs), images and colour maps, the GIF writer,
/// the VTK writers, atomic writes and the crate's error.
pub mod prelude {
    pub use crate::frame::render;
    pub use crate::vtk::{VtkFrame, write_vtu};
    pub use crate::{
        Colormap, FieldValues, FrameStyle, GifWriter, Image, MeshView, RenderError, Rendered, Rgba,
        write_atomic,
    };
}

/// The carried font, DejaVu Sans (Bitstream Vera licence, `assets/DejaVuSans-LICENSE.txt`).
pub const FONT_TTF: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// The font family name to use in SVG output (the PNG path registers [`FONT_TTF`] under it).
pub const FONT_FAMILY: &str = "DejaVu Sans";

// The README's example runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
