use crate::io::ReadLimits;
use crate::{Error, Mesh, Result};
use std::path::Path;

/// Parses the file's bytes. TODO(#2): implement.
pub fn parse(_bytes: &[u8], path: &Path, _limits: &ReadLimits) -> Result<Mesh> {
    Err(Error::invalid(path, "reader not implemented yet"))
}

/// Writes binary little-endian PLY; `scalar` adds a per-vertex float property (name, values),
/// e.g. `("quality", shape_index)` which MeshLab shows as vertex quality.
pub fn write_binary(
    _w: &mut dyn std::io::Write,
    _mesh: &Mesh,
    _scalar: Option<(&str, &[f32])>,
) -> std::io::Result<()> {
    Err(std::io::Error::other("PLY writer not implemented yet"))
}
