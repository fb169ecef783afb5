//! Stanford PLY: reader for ascii, binary_little_endian and binary_big_endian; writer for
//! binary little-endian with an optional per-vertex scalar.
//!
//! The reader takes `x y z` (any numeric type) from the `vertex` element and polygons from the
//! `face` element's list property `vertex_indices` (or `vertex_index`), with any count and index
//! types. Every other property and element (normals, colours, `edge`, `material`, …) is read
//! past according to its declared type, so files from MeshLab, Blender or scanners load whether
//! or not they carry extras. Faces are kept as they are (quads stay quads); consecutive repeated
//! corners are merged and faces left with < 3 corners are dropped, as for every reader.
//!
//! The writer uses `double` coordinates (exact round trip of our f64 millimetres) and
//! `list uchar int vertex_indices`, the layout MeshLab, Blender and CloudCompare all read. A
//! scalar named `quality` is shown by MeshLab as vertex quality (colourise / histogram).

use crate::io::{ReadLimits, push_clean_face};
use crate::mesh::Polygons;
use crate::{Error, Mesh, Result};
use glam::DVec3;
use std::path::Path;

/// Parses a PLY file into a mesh.
pub fn parse(bytes: &[u8], path: &Path, limits: &ReadLimits) -> Result<Mesh> {
    parse_with_scalar(bytes, path, limits, None).map(|(mesh, _)| mesh)
}

/// Parses a PLY file and also returns the per-vertex property `scalar` (e.g. `"quality"`), if
/// the vertex element has it (the values as f32, whatever their stored type).
pub fn parse_with_scalar(
    bytes: &[u8],
    path: &Path,
    limits: &ReadLimits,
    scalar: Option<&str>,
) -> Result<(Mesh, Option<Vec<f32>>)> {
    let header = parse_header(bytes, path)?;
    let data = bytes.get(header.data_start..).unwrap_or(&[]);
    let mut src = match header.format {
        Format::Ascii => Source::Ascii(AsciiSource {
            s: data,
            pos: 0,
            line: header.data_line,
        }),
        Format::BinaryLe => Source::Binary(BinSource {
            s: data,
            pos: 0,
            big_endian: false,
        }),
        Format::BinaryBe => Source::Binary(BinSource {
            s: data,
            pos: 0,
            big_endian: true,
        }),
    };
    let err = |src: &Source, msg: String| -> Error {
        match src {
            Source::Ascii(a) => Error::syntax(path, a.line, msg),
            Source::Binary(b) => Error::invalid(
                path,
                format!("{msg} (at byte {})", header.data_start + b.pos),
            ),
        }
    };

    let mut positions: Vec<DVec3> = Vec::new();
    let mut values: Option<Vec<f32>> = None;
    let mut faces = Polygons::new();
    let mut have_vertices = false;
    let mut face = Vec::new();
    for el in &header.elements {
        // An instance takes at least one byte (binary) or two (ascii), so the data size bounds
        // what may be preallocated whatever the header claims.
        let cap = el.count.min(data.len());
        match el.name.as_str() {
            "vertex" if !have_vertices => {
                have_vertices = true;
                if el.count > limits.max_vertices {
                    return Err(Error::invalid(
                        path,
                        format!(
                            "header declares {} vertices, more than the reader's limit of {} (raise it with --max-vertices)",
                            el.count, limits.max_vertices
                        ),
                    ));
                }
                let find = |n: &str| el.props.iter().position(|p| p.name == n);
                let (Some(ix), Some(iy), Some(iz)) = (find("x"), find("y"), find("z")) else {
                    return Err(Error::invalid(
                        path,
                        "the vertex element lacks an x, y or z property",
                    ));
                };
                for &i in &[ix, iy, iz] {
                    if el.props.get(i).is_some_and(|p| p.list.is_some()) {
                        return Err(Error::invalid(
                            path,
                            "vertex x, y or z is declared as a list",
                        ));
                    }
                }
                let iscalar = scalar.and_then(find);
                positions.reserve(cap);
                let mut vals = iscalar.map(|_| Vec::with_capacity(cap));
                let mut rec = vec![0.0f64; el.props.len()];
                for v in 0..el.count {
                    for (slot, p) in rec.iter_mut().zip(&el.props) {
                        *slot = match p.list {
                            None => src.read(p.ty),
                            Some(count_ty) => src.skip_list(count_ty, p.ty).map(|()| 0.0),
                        }
                        .map_err(|m| err(&src, format!("vertex {v} of {}: {m}", el.count)))?;
                    }
                    let get = |i: usize| rec.get(i).copied().unwrap_or(0.0);
                    let p = DVec3::new(get(ix), get(iy), get(iz));
                    if !p.is_finite() {
                        return Err(err(
                            &src,
                            format!("vertex {v} has a non-finite coordinate {p}"),
                        ));
                    }
                    positions.push(p);
                    if let (Some(vals), Some(i)) = (vals.as_mut(), iscalar) {
                        vals.push(get(i) as f32);
                    }
                }
                values = vals;
            }
            "face" => {
                let Some(il) = el.props.iter().position(|p| {
                    p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
                }) else {
                    return Err(Error::invalid(
                        path,
                        "the face element has no list property vertex_indices",
                    ));
                };
                faces.offsets.reserve(cap);
                for f in 0..el.count {
                    for (k, p) in el.props.iter().enumerate() {
                        let r = match p.list {
                            Some(count_ty) if k == il => {
                                read_face(&mut src, count_ty, p.ty, positions.len(), &mut face)
                            }
                            Some(count_ty) => src.skip_list(count_ty, p.ty),
                            None => src.read(p.ty).map(|_| ()),
                        };
                        r.map_err(|m| err(&src, format!("face {f} of {}: {m}", el.count)))?;
                    }
                    push_clean_face(&mut faces, &mut face, false);
                }
            }
            _ if el.props.is_empty() => {} // nothing stored, whatever the count
            _ => {
                for i in 0..el.count {
                    for p in &el.props {
                        match p.list {
                            Some(count_ty) => src.skip_list(count_ty, p.ty),
                            None => src.read(p.ty).map(|_| ()),
                        }
                        .map_err(|m| err(&src, format!("{} {i} of {}: {m}", el.name, el.count)))?;
                    }
                }
            }
        }
    }
    // Data after the declared elements means the header's counts are wrong, so what was read
    // is not what the file holds (trailing whitespace is harmless).
    if let Some(extra) = src.trailing_bytes() {
        return Err(err(
            &src,
            format!(
                "{extra} bytes of data after the elements the header declares (wrong element counts?)"
            ),
        ));
    }
    if positions.is_empty() {
        return Err(Error::invalid(path, "the file has no vertices"));
    }
    if faces.is_empty() {
        return Err(Error::invalid(
            path,
            "the file has no faces (a point cloud? facesynth triangulates only .xyz/.txt clouds)",
        ));
    }
    Ok((Mesh::new(positions, faces), values))
}

/// Reads one polygon, checking every index against the vertex count.
fn read_face(
    src: &mut Source,
    count_ty: Ty,
    item_ty: Ty,
    n_vertices: usize,
    face: &mut Vec<u32>,
) -> std::result::Result<(), String> {
    face.clear();
    let n = read_count(src, count_ty)?;
    for _ in 0..n {
        let i = src.read(item_ty)?;
        if i < 0.0 || i >= n_vertices as f64 || i.fract() != 0.0 {
            return Err(format!(
                "vertex index {i} is out of range (there are {n_vertices} vertices)"
            ));
        }
        face.push(i as u32);
    }
    Ok(())
}

fn read_count(src: &mut Source, count_ty: Ty) -> std::result::Result<usize, String> {
    let n = src.read(count_ty)?;
    if !(0.0..=1_000_000.0).contains(&n) || n.fract() != 0.0 {
        return Err(format!("list length {n} is negative, fractional or absurd"));
    }
    Ok(n as usize)
}

// ---------------------------------------------------------------------------------------------
// Header

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLe,
    BinaryBe,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn from_name(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }
}

#[derive(Debug)]
struct Prop {
    name: String,
    /// Item type (the only type for scalars).
    ty: Ty,
    /// Count type, for list properties.
    list: Option<Ty>,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    data_start: usize,
    /// Line number of the first data line (for ascii error messages).
    data_line: usize,
}

/// Headers are short; a longer one means this is not a PLY file.
const MAX_HEADER_BYTES: usize = 1 << 20;

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    if bytes.is_empty() {
        return Err(Error::invalid(path, "file is empty"));
    }
    if !(bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n")) {
        return Err(Error::syntax(
            path,
            1,
            "not a PLY file (the first line must be 'ply')",
        ));
    }
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let rest = bytes.get(pos..).unwrap_or(&[]);
        let Some(nl) = rest.iter().position(|&c| c == b'\n') else {
            return Err(Error::syntax(
                path,
                line_no + 1,
                "file ends inside the header (no end_header line)",
            ));
        };
        line_no += 1;
        if pos + nl > MAX_HEADER_BYTES {
            return Err(Error::syntax(path, line_no, "header longer than 1 MiB"));
        }
        let raw = rest.get(..nl).unwrap_or(&[]);
        pos += nl + 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| Error::syntax(path, line_no, "header line is not text"))?;
        let mut words = text.split_ascii_whitespace();
        let bad = |m: &str| Error::syntax(path, line_no, m.to_string());
        match words.next() {
            None | Some("ply") if line_no == 1 => {}
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match (words.next(), words.next()) {
                    (Some("ascii"), Some("1.0")) => Format::Ascii,
                    (Some("binary_little_endian"), Some("1.0")) => Format::BinaryLe,
                    (Some("binary_big_endian"), Some("1.0")) => Format::BinaryBe,
                    _ => return Err(bad(&format!("unknown format line '{}'", text.trim()))),
                });
            }
            Some("element") => {
                let (Some(name), Some(count)) = (words.next(), words.next()) else {
                    return Err(bad("element line needs a name and a count"));
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| bad(&format!("element count '{count}' is not a number")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(el) = elements.last_mut() else {
                    return Err(bad("property before any element"));
                };
                let ty_word = words.next().unwrap_or("");
                let ty_of = |w: &str| {
                    Ty::from_name(w).ok_or_else(|| bad(&format!("unknown property type '{w}'")))
                };
                let prop = if ty_word == "list" {
                    let count_ty = ty_of(words.next().unwrap_or(""))?;
                    let item_ty = ty_of(words.next().unwrap_or(""))?;
                    if !count_ty.is_int() {
                        return Err(bad("list count type must be an integer type"));
                    }
                    let name = words.next().ok_or_else(|| bad("property has no name"))?;
                    Prop {
                        name: name.to_string(),
                        ty: item_ty,
                        list: Some(count_ty),
                    }
                } else {
                    let ty = ty_of(ty_word)?;
                    let name = words.next().ok_or_else(|| bad("property has no name"))?;
                    Prop {
                        name: name.to_string(),
                        ty,
                        list: None,
                    }
                };
                el.props.push(prop);
            }
            Some("end_header") => break,
            Some(other) => {
                return Err(bad(&format!("unknown header keyword '{}'", other)));
            }
        }
    }
    let format = format.ok_or_else(|| Error::syntax(path, line_no, "header has no format line"))?;
    Ok(Header {
        format,
        elements,
        data_start: pos,
        data_line: line_no + 1,
    })
}

// ---------------------------------------------------------------------------------------------
// Data

enum Source<'a> {
    Ascii(AsciiSource<'a>),
    Binary(BinSource<'a>),
}

struct AsciiSource<'a> {
    s: &'a [u8],
    pos: usize,
    line: usize,
}

struct BinSource<'a> {
    s: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Source<'_> {
    fn read(&mut self, ty: Ty) -> std::result::Result<f64, String> {
        match self {
            Source::Ascii(a) => a.read(ty),
            Source::Binary(b) => b.read(ty),
        }
    }

    /// How many bytes follow the read position, if any of them is not whitespace.
    fn trailing_bytes(&self) -> Option<usize> {
        let (s, pos) = match self {
            Source::Ascii(a) => (a.s, a.pos),
            Source::Binary(b) => (b.s, b.pos),
        };
        let rest = s.get(pos..).unwrap_or(&[]);
        rest.iter()
            .any(|c| !c.is_ascii_whitespace())
            .then_some(rest.len())
    }

    fn skip_list(&mut self, count_ty: Ty, item_ty: Ty) -> std::result::Result<(), String> {
        let n = read_count(self, count_ty)?;
        match self {
            Source::Binary(b) => {
                let len = n * item_ty.size();
                if b.s.len() - b.pos < len {
                    return Err("file ends inside a list (truncated file?)".into());
                }
                b.pos += len;
            }
            Source::Ascii(a) => {
                for _ in 0..n {
                    a.read(item_ty)?;
                }
            }
        }
        Ok(())
    }
}

impl AsciiSource<'_> {
    fn read(&mut self, ty: Ty) -> std::result::Result<f64, String> {
        let s = self.s;
        while let Some(&c) = s.get(self.pos) {
            if c == b'\n' {
                self.line += 1;
            } else if !c.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while s.get(self.pos).is_some_and(|c| !c.is_ascii_whitespace()) {
            self.pos += 1;
        }
        let word = s.get(start..self.pos).unwrap_or(&[]);
        if word.is_empty() {
            return Err("file ends early (truncated file?)".into());
        }
        let text = std::str::from_utf8(word).unwrap_or("");
        let v = text
            .parse::<f64>()
            .ok()
            .filter(|v| !ty.is_int() || v.fract() == 0.0);
        v.ok_or_else(|| {
            let shown: String = String::from_utf8_lossy(word).chars().take(40).collect();
            format!("expected {ty:?} value, found '{shown}'")
        })
    }
}

impl BinSource<'_> {
    fn read(&mut self, ty: Ty) -> std::result::Result<f64, String> {
        let n = ty.size();
        let Some(b) = self.s.get(self.pos..self.pos + n) else {
            return Err("file ends early (truncated file?)".into());
        };
        self.pos += n;
        let mut a = [0u8; 8];
        if let Some(dst) = a.get_mut(..n) {
            dst.copy_from_slice(b);
        }
        if self.big_endian
            && let Some(dst) = a.get_mut(..n)
        {
            dst.reverse();
        }
        let [b0, b1, b2, b3, ..] = a;
        Ok(match ty {
            Ty::I8 => b0 as i8 as f64,
            Ty::U8 => b0 as f64,
            Ty::I16 => i16::from_le_bytes([b0, b1]) as f64,
            Ty::U16 => u16::from_le_bytes([b0, b1]) as f64,
            Ty::I32 => i32::from_le_bytes([b0, b1, b2, b3]) as f64,
            Ty::U32 => u32::from_le_bytes([b0, b1, b2, b3]) as f64,
            Ty::F32 => f32::from_le_bytes([b0, b1, b2, b3]) as f64,
            Ty::F64 => f64::from_le_bytes(a),
        })
    }
}

// ---------------------------------------------------------------------------------------------
// Writer

/// Writes binary little-endian PLY; `scalar` adds a per-vertex float property (name, values),
/// e.g. `("quality", shape_index)` which MeshLab shows as vertex quality.
///
/// Fails (`InvalidInput`) when the scalar's length differs from the vertex count, its name is
/// not a single word, a face has more than 255 corners, or there are more than 2³¹ vertices.
pub fn write_binary(
    w: &mut dyn std::io::Write,
    mesh: &Mesh,
    scalar: Option<(&str, &[f32])>,
) -> std::io::Result<()> {
    let invalid = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidInput, m);
    let n = mesh.positions_mm.len();
    if let Some((name, values)) = scalar {
        if values.len() != n {
            return Err(invalid(format!(
                "PLY scalar '{name}' has {} values for {n} vertices",
                values.len()
            )));
        }
        if name.is_empty()
            || !name.bytes().all(|c| c.is_ascii_graphic())
            || matches!(name, "x" | "y" | "z")
        {
            return Err(invalid(format!(
                "PLY scalar name '{name}' must be one word and not x, y or z"
            )));
        }
    }
    if n > i32::MAX as usize {
        return Err(invalid("too many vertices for PLY int indices".into()));
    }
    if let Some(big) = mesh.faces.iter().find(|f| f.len() > 255) {
        return Err(invalid(format!(
            "a face has {} corners; PLY uchar counts allow 255",
            big.len()
        )));
    }
    let mut head = String::new();
    head.push_str("ply\nformat binary_little_endian 1.0\n");
    head.push_str("comment facesynth mesh, units: millimetres\n");
    head.push_str(&format!("element vertex {n}\n"));
    head.push_str("property double x\nproperty double y\nproperty double z\n");
    if let Some((name, _)) = scalar {
        head.push_str(&format!("property float {name}\n"));
    }
    head.push_str(&format!("element face {}\n", mesh.faces.len()));
    head.push_str("property list uchar int vertex_indices\nend_header\n");
    w.write_all(head.as_bytes())?;

    let mut buf = Vec::with_capacity(n * 28 + mesh.faces.indices.len() * 4 + mesh.faces.len());
    for (i, p) in mesh.positions_mm.iter().enumerate() {
        for c in p.to_array() {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        if let Some((_, values)) = scalar {
            let v = values.get(i).copied().unwrap_or(0.0);
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }
    for f in mesh.faces.iter() {
        buf.push(f.len() as u8);
        for &v in f {
            buf.extend_from_slice(&(v as i32).to_le_bytes());
        }
    }
    w.write_all(&buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &[u8]) -> Result<Mesh> {
        parse(s, Path::new("t.ply"), &ReadLimits::default())
    }

    #[test]
    fn ascii_with_extras_and_other_list_types() {
        let m = p(
            b"ply\r\nformat ascii 1.0\r\ncomment hi\r\nelement vertex 4\r\n\
            property float x\r\nproperty float y\r\nproperty uchar red\r\nproperty float z\r\n\
            property list uchar float junk\r\n\
            element face 2\r\nproperty uchar flags\r\nproperty list ushort uint vertex_index\r\n\
            element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n\
            0 0 255 0 2 0.5 0.5\r\n1 0 0 0 0\r\n1 1 0 0 1 7\r\n0 1 0 0 0\r\n\
            3 4 0 1 2 3\r\n0 3 0 2 3\r\n0 1\r\n",
        )
        .unwrap();
        assert_eq!(m.vertex_count(), 4);
        assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
        assert_eq!(m.faces.get(1), &[0, 2, 3]);
    }

    #[test]
    fn big_endian_is_read() {
        let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n\
            property float y\nproperty float z\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.push(3);
        for i in [0i32, 1, 2] {
            b.extend_from_slice(&i.to_be_bytes());
        }
        let m = p(&b).unwrap();
        assert_eq!(m.positions_mm[1], DVec3::X);
        assert_eq!(m.faces.get(0), &[0, 1, 2]);
    }
}
