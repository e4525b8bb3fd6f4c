//! Multiscale cages for pictures of plants (seed 004, Wang et al. 2018, "Sketch-based
//! shape-preserving tree animations"): pure geometry, no I/O.
//!
//! - [`mvc`]: 2D mean value coordinates (section 5.3, step 1), the way a cage carries its content;
//! - [`outline`]: closed outlines: signed area, arc-length resampling, simplification, and the
//!   discrete Frechet distance used for the quality of the in-betweens (section 6.2);
//! - [`laplacian`]: Eq. 1, Laplacian editing of a polyline with constraint vertices;
//! - [`contour`]: the outlines of a vegetation mask's connected parts, traced along pixel edges;
//! - [`tree`]: the multiscale cage tree (section 5.2) and its `cage.json` form, validated on read;
//! - [`build`]: a cage tree from a mask: crowns, lobes clustered inside them, level by level.

#![warn(missing_docs)]

pub mod build;
pub mod contour;
pub mod laplacian;
pub mod morph;
pub mod mvc;
pub mod outline;
pub mod raster;
pub mod sketch;
pub mod tree;

pub use build::{BuildOptions, build_cage_tree};
pub use tree::{Cage, CageError, CageKind, CageTree};

/// A point in image pixels: `[x, y]`, x to the right, y down.
pub type Point = [f64; 2];
