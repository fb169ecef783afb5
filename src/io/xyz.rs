use crate::io::ReadLimits;
use crate::{Error, Mesh, Result};
use std::path::Path;

/// Parses the file's bytes. TODO(#2): implement.
pub fn parse(_bytes: &[u8], path: &Path, _limits: &ReadLimits) -> Result<Mesh> {
    Err(Error::invalid(path, "reader not implemented yet"))
}
