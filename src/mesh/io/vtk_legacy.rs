//! Reader for this format (in progress).

use std::path::Path;

use super::RawMesh;
use crate::error::{Error, Result};

/// Parse a file of this format.
pub fn parse(_bytes: &[u8], path: &Path) -> Result<RawMesh> {
    Err(Error::Unsupported(format!(
        "{}: reader not written yet",
        path.display()
    )))
}
