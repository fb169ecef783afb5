//! VRML 1.0 and 2.0 (VRML97) reader: the indexed face sets of a scene, merged into one mesh.
//!
//! GavabDB scans come from a Minolta VIVID exporter in VRML 1.0:
//! `Separator { Transform { scaleFactor 0.5 0.5 0.5 } Group { Group { Separator {
//! Transform { translation 0 0 0 } Coordinate3 { point [..] } ShapeHints {..}
//! IndexedFaceSet { coordIndex [..] } } } } }`. The header line picks the dialect
//! (`#VRML V1.0 ascii`, or `#VRML V2.0 utf8` / `#X3D V3.x utf8` for VRML97 semantics).
//!
//! The file is read by a small tokenizer and a schema-free node parser: a word followed by `{`
//! opens a node, `DEF`/`USE` name and share nodes, and only the handful of fields that matter
//! for geometry are decoded (`point`, `coordIndex`, `ccw`, `vertexOrdering`, `translation`,
//! `rotation`, `center`). Every other field value is skipped token by token, while nodes nested
//! anywhere inside it (e.g. `children [..]` of an unknown grouping node) are still visited.
//! `PROTO`/`EXTERNPROTO` declarations are skipped; instances of prototypes are not expanded.
//!
//! Scene semantics:
//! * VRML 1.0: nodes are traversed in order with a state of (transform, current `Coordinate3`,
//!   vertex ordering); `Separator` saves and restores the whole state, `TransformSeparator` the
//!   transform; every other group shares it. An `IndexedFaceSet` uses the most recent
//!   `Coordinate3` in scope.
//! * VRML 2.0: `Transform { children [..] }` nests, and an `IndexedFaceSet` uses its own
//!   `coord Coordinate { point [..] }` (or `coord USE name`).
//! * Every face set's points are appended (once per distinct coordinate node and transform) and
//!   its faces offset accordingly, so a file with several shapes gives one merged mesh. Points
//!   of a coordinate node that no face set uses are not included.
//! * Faces are split at `-1`; the last face may lack it. Consecutive repeated corners are
//!   merged and faces left with fewer than three distinct corners are dropped (both are
//!   zero-area). A face with an index below -1 or past the end of its coordinates is an error.
//! * Faces are returned counter-clockwise: `ccw FALSE` (2.0) and `vertexOrdering CLOCKWISE`
//!   (1.0 `ShapeHints`) reverse them.
//!
//! Units and transforms: coordinates are taken to be millimetres, as GavabDB's are (the cara1
//! scans, face with hair and neck, are 178–253 mm wide and lie about 1.25 m in front of the
//! scanner, z ≈ −1250). The rigid part of a transform is applied —
//! `translation`, `rotation` and `center` of `Transform` (both dialects) and the 1.0
//! `Translation`/`Rotation` nodes — since it moves parts without changing units. Scaling is
//! ignored: `scaleFactor`/`scale`/`scaleOrientation` and the 1.0 `Scale` and `MatrixTransform`
//! nodes. The VIVID exporter writes `scaleFactor 0.5 0.5 0.5` as a display scale while its
//! points are already millimetres; honouring it would halve every GavabDB face. (Every
//! translation in GavabDB is zero and none has a rotation, so the scans come out exactly as
//! their points are written.)
//!
//! Not handled: gzip-compressed files (a clear error), `Inline`/`WWWInline` (not fetched),
//! `Switch`/`LOD` (all children are read, not just the chosen one), other geometry nodes
//! (`Box`, `Sphere`, `ElevationGrid`, …; ignored).
//!
//! Speed: one pass over the bytes, no regexes, no per-token allocation. Measured with
//! `tests/io/io_timing.rs` (release): the nine cara1 scans (0.63–0.86 MB) take 25–36 ms of CPU on
//! the shared 2-core development machine under load ≈ 12, where merely splitting
//! cara1_frontal1.wrl into words and parsing its numbers takes 17 ms; i.e. the reader costs
//! ~1.5–2× that floor, which on an unloaded core is a few milliseconds.

use crate::io::ReadLimits;
use crate::mesh::Polygons;
use crate::{Error, Mesh, Result};
use glam::{DAffine3, DVec3};
use std::collections::HashMap;
use std::path::Path;

mod lexer;
mod scene;

use lexer::*;
use scene::*;

/// Deepest node nesting accepted (real files nest < 10; garbage could overflow the stack).
const MAX_DEPTH: usize = 200;
/// Most node visits during evaluation: `USE` can make a scene graph exponentially large.
const MAX_VISITS: usize = 1_000_000;

/// Parses a VRML 1.0 or 2.0 file into one mesh (see the module doc for the rules).
pub fn parse(bytes: &[u8], path: &Path, limits: &ReadLimits) -> Result<Mesh> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    if bytes.starts_with(&[0x1f, 0x8b]) {
        return Err(Error::invalid(
            path,
            "gzip-compressed VRML is not supported (gunzip the file first)",
        ));
    }
    let dialect = if bytes.starts_with(b"#VRML V1.0") {
        Dialect::V1
    } else if bytes.starts_with(b"#VRML V2.0") || bytes.starts_with(b"#X3D V3") {
        Dialect::V2
    } else if bytes.is_empty() {
        return Err(Error::invalid(path, "file is empty"));
    } else {
        return Err(Error::syntax(
            path,
            1,
            "not a VRML file (the first line must be '#VRML V1.0 ascii' or '#VRML V2.0 utf8')",
        ));
    };
    let mut parser = Parser {
        lex: Lexer::new(bytes),
        path,
        limits,
        nodes: Vec::new(),
        defs: HashMap::new(),
        total_points: 0,
    };
    let roots = parser.parse_top()?;
    // Without USE a file cannot describe more points or corners than it has bytes; with USE a
    // small file can describe exponentially many, so what it may expand to is bounded.
    let budget = bytes.len().saturating_mul(4).max(1 << 20);
    let mut ev = Evaluator {
        budget,
        nodes: &parser.nodes,
        path,
        limits,
        positions: Vec::new(),
        faces: Polygons::new(),
        placed: Vec::new(),
        visits: 0,
        scratch: Vec::new(),
    };
    match dialect {
        Dialect::V1 => {
            let mut state = State1 {
                xf: DAffine3::IDENTITY,
                coord: None,
                clockwise: false,
            };
            for id in roots {
                ev.eval1(id, &mut state, 0)?;
            }
        }
        Dialect::V2 => {
            for id in roots {
                ev.eval2(id, &DAffine3::IDENTITY, 0)?;
            }
        }
    }
    if ev.faces.is_empty() {
        return Err(Error::invalid(
            path,
            "no faces found (the file has no IndexedFaceSet with a non-empty coordIndex)",
        ));
    }
    Ok(Mesh::new(ev.positions, ev.faces))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dialect {
    V1,
    V2,
}

// ---------------------------------------------------------------------------------------------
// Parser: builds an arena of nodes. Children refer to earlier-completed nodes only through
// `USE`, so the graph is acyclic.

#[derive(Debug, Default)]
struct Node<'a> {
    kind: &'a [u8],
    line: usize,
    /// Nested nodes in file order, with the field name that preceded them (if any).
    children: Vec<(Option<&'a [u8]>, usize)>,
    /// `point` of `Coordinate3` / `Coordinate`.
    points: Vec<DVec3>,
    /// `coordIndex` of `IndexedFaceSet`, and the line it starts on.
    coord_index: Vec<i64>,
    coord_index_line: usize,
    translation: Option<DVec3>,
    /// Axis and angle (radians).
    rotation: Option<(DVec3, f64)>,
    center: Option<DVec3>,
    /// `ccw FALSE` (2.0) or `vertexOrdering CLOCKWISE` (1.0) → `Some(true)`.
    clockwise: Option<bool>,
}

struct Parser<'a, 'p> {
    lex: Lexer<'a>,
    path: &'p Path,
    limits: &'p ReadLimits,
    nodes: Vec<Node<'a>>,
    defs: HashMap<&'a [u8], usize>,
    total_points: usize,
}

impl<'a> Parser<'a, '_> {
    fn err(&self, line: usize, message: impl Into<String>) -> Error {
        Error::syntax(self.path, line, message)
    }

    fn next(&mut self) -> Result<Tok<'a>> {
        self.lex
            .next()
            .map_err(|(l, m)| Error::syntax(self.path, l, m))
    }

    fn peek(&mut self) -> Result<Tok<'a>> {
        self.lex
            .peek()
            .map_err(|(l, m)| Error::syntax(self.path, l, m))
    }

    fn parse_top(&mut self) -> Result<Vec<usize>> {
        let mut roots = Vec::new();
        self.parse_items(None, &mut roots, 0)?;
        Ok(roots.into_iter().map(|(_, id)| id).collect())
    }

    /// Reads node contents (or the top level when `owner` is `None`) up to the closing `}`
    /// (or end of file), collecting nested nodes into `children`.
    fn parse_items(
        &mut self,
        owner: Option<(usize, &'a [u8], usize)>,
        children: &mut Vec<(Option<&'a [u8]>, usize)>,
        depth: usize,
    ) -> Result<()> {
        let mut brackets = 0usize;
        let mut field: Option<&'a [u8]> = None;
        loop {
            let tok = self.next()?;
            match tok.kind {
                Kind::Eof => {
                    return match owner {
                        None if brackets == 0 => Ok(()),
                        None => Err(self.err(tok.line, "file ends inside a '[' list")),
                        Some((_, kind, line)) => Err(self.err(
                            tok.line,
                            format!(
                                "file ends inside the {} node opened on line {line} \
                                 (truncated file?)",
                                show(kind)
                            ),
                        )),
                    };
                }
                Kind::Close => {
                    if owner.is_none() {
                        return Err(self.err(tok.line, "'}' without a matching '{'"));
                    }
                    if brackets != 0 {
                        return Err(self.err(tok.line, "'}' inside an unclosed '[' list"));
                    }
                    return Ok(());
                }
                Kind::Open => return Err(self.err(tok.line, "unexpected '{'")),
                Kind::LBracket => brackets += 1,
                Kind::RBracket => {
                    if brackets == 0 {
                        return Err(self.err(tok.line, "']' without a matching '['"));
                    }
                    brackets -= 1;
                }
                Kind::Str => {}
                Kind::Word => {
                    let w = tok.text;
                    if w == b"PROTO" {
                        self.skip_proto(tok.line, true)?;
                        continue;
                    }
                    if w == b"EXTERNPROTO" {
                        self.skip_proto(tok.line, false)?;
                        continue;
                    }
                    if w == b"DEF" {
                        let name = self.expect_word("a name after DEF")?;
                        let ty = self.expect_word("a node type after DEF name")?;
                        let id = self.parse_node(ty.text, ty.line, depth)?;
                        self.defs.insert(name.text, id);
                        children.push((field.take(), id));
                        continue;
                    }
                    if w == b"USE" {
                        let name = self.expect_word("a name after USE")?;
                        let Some(&id) = self.defs.get(name.text) else {
                            return Err(self.err(
                                name.line,
                                format!("USE of '{}', which no DEF names", show(name.text)),
                            ));
                        };
                        children.push((field.take(), id));
                        continue;
                    }
                    if self.peek()?.kind == Kind::Open {
                        let id = self.parse_node(w, tok.line, depth)?;
                        children.push((field.take(), id));
                        continue;
                    }
                    if let Some((id, kind, _)) = owner
                        && self.parse_known_field(id, kind, tok)?
                    {
                        field = None;
                        continue;
                    }
                    if w.first().is_some_and(u8::is_ascii_lowercase) {
                        field = Some(w);
                    }
                }
            }
        }
    }

    fn expect_word(&mut self, what: &str) -> Result<Tok<'a>> {
        let t = self.next()?;
        if t.kind == Kind::Word {
            Ok(t)
        } else if t.kind == Kind::Eof {
            Err(self.err(t.line, format!("file ends where {what} was expected")))
        } else {
            Err(self.err(t.line, format!("expected {what}, found '{}'", show(t.text))))
        }
    }

    /// Parses `Type { ... }` (the type word already read) and returns the node's id.
    fn parse_node(&mut self, kind: &'a [u8], line: usize, depth: usize) -> Result<usize> {
        if depth >= MAX_DEPTH {
            return Err(self.err(line, format!("nodes nested more than {MAX_DEPTH} deep")));
        }
        let open = self.next()?;
        if open.kind != Kind::Open {
            return Err(self.err(
                open.line,
                format!(
                    "expected '{{' after {}, found '{}'",
                    show(kind),
                    show(open.text)
                ),
            ));
        }
        let id = self.nodes.len();
        self.nodes.push(Node {
            kind,
            line,
            ..Node::default()
        });
        let mut children = Vec::new();
        self.parse_items(Some((id, kind, line)), &mut children, depth + 1)?;
        if let Some(node) = self.nodes.get_mut(id) {
            node.children = children;
        }
        Ok(id)
    }

    /// `PROTO name [ interface ] { body }` or `EXTERNPROTO name [ interface ] url`.
    fn skip_proto(&mut self, line: usize, has_body: bool) -> Result<()> {
        self.expect_word("a prototype name")?;
        let t = self.next()?;
        if t.kind != Kind::LBracket {
            return Err(self.err(t.line, "expected '[' after the prototype name"));
        }
        self.skip_balanced(Kind::LBracket, Kind::RBracket, line)?;
        if has_body {
            let t = self.next()?;
            if t.kind != Kind::Open {
                return Err(self.err(t.line, "expected '{' to open the prototype body"));
            }
            self.skip_balanced(Kind::Open, Kind::Close, line)
        } else {
            let t = self.next()?;
            match t.kind {
                Kind::Str => Ok(()),
                Kind::LBracket => self.skip_balanced(Kind::LBracket, Kind::RBracket, line),
                _ => Err(self.err(t.line, "expected the EXTERNPROTO url")),
            }
        }
    }

    /// Skips to the token closing an already-opened `open`.
    fn skip_balanced(&mut self, open: Kind, close: Kind, line: usize) -> Result<()> {
        let mut depth = 1usize;
        loop {
            let t = self.next()?;
            if t.kind == Kind::Eof {
                return Err(self.err(
                    t.line,
                    format!("file ends inside the prototype started on line {line}"),
                ));
            }
            if t.kind == open {
                depth += 1;
            } else if t.kind == close {
                depth -= 1;
                if depth == 0 {
                    return Ok(());
                }
            }
        }
    }

    /// Decodes the fields that matter for geometry; returns false for any other word.
    fn parse_known_field(&mut self, id: usize, kind: &[u8], tok: Tok<'a>) -> Result<bool> {
        let f = tok.text;
        match (kind, f) {
            (b"Coordinate3" | b"Coordinate", b"point") => {
                let pts = self.parse_vec3_list(tok.line)?;
                if let Some(n) = self.nodes.get_mut(id) {
                    n.points = pts;
                }
            }
            (b"IndexedFaceSet", b"coordIndex") => {
                let idx = self.parse_int_list()?;
                if let Some(n) = self.nodes.get_mut(id) {
                    n.coord_index = idx;
                    n.coord_index_line = tok.line;
                }
            }
            (b"IndexedFaceSet", b"ccw") => {
                let t = self.expect_word("TRUE or FALSE after ccw")?;
                let cw = match t.text {
                    b"TRUE" => false,
                    b"FALSE" => true,
                    other => {
                        return Err(self.err(
                            t.line,
                            format!("ccw must be TRUE or FALSE, not '{}'", show(other)),
                        ));
                    }
                };
                if let Some(n) = self.nodes.get_mut(id) {
                    n.clockwise = Some(cw);
                }
            }
            (b"ShapeHints", b"vertexOrdering") => {
                let t = self.expect_word("a vertexOrdering value")?;
                let cw = t.text == b"CLOCKWISE";
                if let Some(n) = self.nodes.get_mut(id) {
                    n.clockwise = Some(cw);
                }
            }
            (b"Transform" | b"Translation", b"translation") | (b"Transform", b"center") => {
                let v = self.parse_vec3_single(tok.text)?;
                if let Some(n) = self.nodes.get_mut(id) {
                    if f == b"center" {
                        n.center = Some(v);
                    } else {
                        n.translation = Some(v);
                    }
                }
            }
            (b"Transform" | b"Rotation", b"rotation") => {
                let mut v = [0.0; 4];
                for x in &mut v {
                    *x = self.parse_number("rotation")?;
                }
                if let Some(n) = self.nodes.get_mut(id) {
                    n.rotation = Some((DVec3::new(v[0], v[1], v[2]), v[3]));
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    fn parse_number(&mut self, field: &str) -> Result<f64> {
        let t = self.next()?;
        if t.kind == Kind::Eof {
            return Err(self.err(t.line, format!("file ends inside {field}")));
        }
        let v = (t.kind == Kind::Word)
            .then(|| parse_f64(t.text))
            .flatten()
            .ok_or_else(|| {
                self.err(
                    t.line,
                    format!("expected a number in {field}, found '{}'", show(t.text)),
                )
            })?;
        if !v.is_finite() {
            return Err(self.err(
                t.line,
                format!("non-finite number '{}' in {field}", show(t.text)),
            ));
        }
        Ok(v)
    }

    fn parse_vec3_single(&mut self, field: &[u8]) -> Result<DVec3> {
        let name = String::from_utf8_lossy(field).into_owned();
        Ok(DVec3::new(
            self.parse_number(&name)?,
            self.parse_number(&name)?,
            self.parse_number(&name)?,
        ))
    }

    /// `[ x y z, x y z, ... ]` or a single `x y z`.
    fn parse_vec3_list(&mut self, line: usize) -> Result<Vec<DVec3>> {
        if self.peek()?.kind != Kind::LBracket {
            self.add_points(1, line)?;
            return Ok(vec![self.parse_vec3_single(b"point")?]);
        }
        self.next()?;
        let mut out = Vec::new();
        let mut xyz = [0.0; 3];
        let mut k = 0;
        loop {
            let t = self.next()?;
            match t.kind {
                Kind::RBracket => break,
                Kind::Word => {
                    let v = parse_f64(t.text).ok_or_else(|| {
                        self.err(
                            t.line,
                            format!("expected a number in point, found '{}'", show(t.text)),
                        )
                    })?;
                    if !v.is_finite() {
                        return Err(self.err(
                            t.line,
                            format!(
                                "point {} has a non-finite coordinate '{}'",
                                out.len(),
                                show(t.text)
                            ),
                        ));
                    }
                    if let Some(x) = xyz.get_mut(k) {
                        *x = v;
                    }
                    k += 1;
                    if k == 3 {
                        out.push(DVec3::from_array(xyz));
                        k = 0;
                        if out.len() % 4096 == 0 {
                            self.add_points(4096, t.line)?;
                        }
                    }
                }
                Kind::Eof => {
                    return Err(self.err(
                        t.line,
                        format!("file ends inside the point list started on line {line}"),
                    ));
                }
                _ => {
                    return Err(self.err(
                        t.line,
                        format!("expected a number in point, found '{}'", show(t.text)),
                    ));
                }
            }
        }
        if k != 0 {
            return Err(self.err(
                line,
                "point list length is not a multiple of 3 (a coordinate is missing)",
            ));
        }
        self.add_points(out.len() % 4096, line)?;
        Ok(out)
    }

    fn add_points(&mut self, n: usize, line: usize) -> Result<()> {
        self.total_points += n;
        if self.total_points > self.limits.max_vertices {
            return Err(self.err(
                line,
                format!(
                    "more than {} points (the reader's vertex limit; raise it with --max-vertices)",
                    self.limits.max_vertices
                ),
            ));
        }
        Ok(())
    }

    /// `[ i, j, ... ]` or a single integer.
    fn parse_int_list(&mut self) -> Result<Vec<i64>> {
        let one = |p: &mut Self, t: Tok<'a>| {
            (t.kind == Kind::Word)
                .then(|| parse_i64(t.text))
                .flatten()
                .ok_or_else(|| {
                    p.err(
                        t.line,
                        format!(
                            "expected an integer in coordIndex, found '{}'",
                            show(t.text)
                        ),
                    )
                })
        };
        if self.peek()?.kind != Kind::LBracket {
            let t = self.next()?;
            return Ok(vec![one(self, t)?]);
        }
        let start = self.next()?.line;
        let mut out = Vec::new();
        loop {
            let t = self.next()?;
            match t.kind {
                Kind::RBracket => return Ok(out),
                Kind::Eof => {
                    return Err(self.err(
                        t.line,
                        format!("file ends inside the coordIndex list started on line {start}"),
                    ));
                }
                _ => out.push(one(self, t)?),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<Mesh> {
        parse(s.as_bytes(), Path::new("t.wrl"), &ReadLimits::default())
    }

    #[test]
    fn minimal_v1_with_quad_and_open_last_face() {
        let m = parse_str(
            "#VRML V1.0 ascii\nSeparator { Coordinate3 { point [0 0 0, 1 0 0, 1 1 0, 0 1 0, 2 0 0] }\n\
             IndexedFaceSet { coordIndex [0, 1, 2, 3, -1, 1, 4, 2] } }",
        )
        .unwrap();
        assert_eq!(m.vertex_count(), 5);
        assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
        assert_eq!(m.faces.get(1), &[1, 4, 2]);
    }

    #[test]
    fn separator_scopes_coordinates_and_scale_is_ignored() {
        let m = parse_str(
            "#VRML V1.0 ascii\nSeparator { Transform { scaleFactor 0.5 0.5 0.5 translation 0 0 0 }\n\
             Coordinate3 { point [0 0 0, 1 0 0, 0 1 0] }\n\
             Separator { Translation { translation 10 0 0 } Coordinate3 { point [5 5 5, 6 5 5, 5 6 5] }\n\
               IndexedFaceSet { coordIndex [0 1 2 -1] } }\n\
             IndexedFaceSet { coordIndex [0 1 2 -1] } }",
        )
        .unwrap();
        assert_eq!(m.vertex_count(), 6);
        assert_eq!(m.positions_mm[0], DVec3::new(15.0, 5.0, 5.0));
        assert_eq!(m.positions_mm[4], DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(m.faces.get(1), &[3, 4, 5]);
    }

    #[test]
    fn clockwise_shape_hints_reverse_faces() {
        let m = parse_str(
            "#VRML V1.0 ascii\nSeparator { ShapeHints { vertexOrdering CLOCKWISE }\n\
             Coordinate3 { point [0 0 0, 1 0 0, 0 1 0] } IndexedFaceSet { coordIndex [0 1 2] } }",
        )
        .unwrap();
        assert_eq!(m.faces.get(0), &[2, 1, 0]);
    }

    #[test]
    fn out_of_range_index_is_an_error_naming_the_line() {
        let e = parse_str(
            "#VRML V1.0 ascii\nSeparator { Coordinate3 { point [0 0 0, 1 0 0, 0 1 0] }\n\
             IndexedFaceSet { coordIndex [0 1 7 -1] } }",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("t.wrl: line 3") && e.contains("point 7"), "{e}");
    }

    #[test]
    fn deep_nesting_and_use_explosions_are_refused() {
        let deep = format!("#VRML V1.0 ascii\n{}", "Separator { ".repeat(100_000));
        let e = parse_str(&deep).unwrap_err().to_string();
        assert!(e.contains("nested more than"), "{e}");
        // Each level uses the previous one twice: 2^60 face sets if expanded.
        let mut s = String::from(
            "#VRML V2.0 utf8\nDEF L0 Shape { geometry IndexedFaceSet { coord Coordinate \
             { point [0 0 0 1 0 0 0 1 0] } coordIndex [0 1 2] } }\n",
        );
        for k in 1..=60 {
            s.push_str(&format!(
                "DEF L{k} Group {{ children [USE L{} USE L{}] }}\n",
                k - 1,
                k - 1
            ));
        }
        let e = parse_str(&s).unwrap_err().to_string();
        assert!(
            e.contains("expands to more than") || e.contains("too large"),
            "{e}"
        );
    }

    #[test]
    fn truncated_file_is_an_error() {
        let e = parse_str("#VRML V1.0 ascii\nSeparator { Coordinate3 { point [0 0 0, 1 0")
            .unwrap_err()
            .to_string();
        assert!(e.contains("file ends"), "{e}");
    }
}
