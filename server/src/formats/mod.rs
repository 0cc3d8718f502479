//! The standard formats Relief speaks besides its own streams (DESIGN.md section 6b), each
//! resampled from the store through its georeference.
//!
//! - [`sampler`]: the store's heights at longitudes and latitudes of a tile scheme.

pub mod sampler;
