//! Reader for TetGen `.node`/`.ele` pairs (in progress).

use std::path::Path;

use super::LoadedMesh;
use crate::error::{Error, Result};

/// Read the pair given either file of it.
pub fn read_pair(path: &Path) -> Result<LoadedMesh> {
    Err(Error::Unsupported(format!(
        "{}: reader not written yet",
        path.display()
    )))
}
