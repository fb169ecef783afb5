//! Evaluating the parsed VRML scene graph: transforms, DEF/USE, the IndexedFaceSets gathered
//! into one mesh in millimetres.

use super::*;

#[derive(Debug, Clone, Copy)]
pub(super) struct State1 {
    pub(super) xf: DAffine3,
    pub(super) coord: Option<usize>,
    pub(super) clockwise: bool,
}

pub(super) struct Evaluator<'n, 'a, 'p> {
    /// Most points, and most face corners, the scene may expand to.
    pub(super) budget: usize,
    pub(super) nodes: &'n [Node<'a>],
    pub(super) path: &'p Path,
    pub(super) limits: &'p ReadLimits,
    pub(super) positions: Vec<DVec3>,
    pub(super) faces: Polygons,
    /// (coordinate node, transform, first vertex) for each block of points already appended.
    pub(super) placed: Vec<(usize, DAffine3, u32)>,
    pub(super) visits: usize,
    pub(super) scratch: Vec<u32>,
}

/// The rigid part of a `Transform`/`Translation`/`Rotation` node: T · C · R · C⁻¹.
pub(super) fn rigid_transform(node: &Node) -> DAffine3 {
    let t = node.translation.unwrap_or(DVec3::ZERO);
    let c = node.center.unwrap_or(DVec3::ZERO);
    let r = match node.rotation {
        Some((axis, angle)) if axis.length_squared() > 0.0 => {
            DAffine3::from_axis_angle(axis.normalize(), angle)
        }
        _ => DAffine3::IDENTITY,
    };
    DAffine3::from_translation(t + c) * r * DAffine3::from_translation(-c)
}

impl Evaluator<'_, '_, '_> {
    pub(super) fn node(&self, id: usize) -> Result<&Node<'_>> {
        self.nodes
            .get(id)
            .ok_or_else(|| Error::invalid(self.path, "internal error: bad node id"))
    }

    pub(super) fn visit(&mut self, line: usize, depth: usize) -> Result<()> {
        self.visits += 1;
        if self.visits > MAX_VISITS || depth > MAX_DEPTH {
            return Err(Error::syntax(
                self.path,
                line,
                "scene graph too large (USE expands it past a million nodes)",
            ));
        }
        Ok(())
    }

    pub(super) fn eval1(&mut self, id: usize, state: &mut State1, depth: usize) -> Result<()> {
        let nodes = self.nodes;
        let node = nodes
            .get(id)
            .ok_or_else(|| Error::invalid(self.path, "internal error: bad node id"))?;
        self.visit(node.line, depth)?;
        match node.kind {
            b"Separator" => {
                let mut inner = *state;
                for &(_, c) in &node.children {
                    self.eval1(c, &mut inner, depth + 1)?;
                }
            }
            b"TransformSeparator" => {
                let saved = state.xf;
                for &(_, c) in &node.children {
                    self.eval1(c, state, depth + 1)?;
                }
                state.xf = saved;
            }
            b"Transform" | b"Translation" | b"Rotation" => {
                state.xf *= rigid_transform(node);
            }
            b"Coordinate3" => state.coord = Some(id),
            b"ShapeHints" => {
                if let Some(cw) = node.clockwise {
                    state.clockwise = cw;
                }
            }
            b"IndexedFaceSet" => {
                let (xf, coord, cw) = (state.xf, state.coord, state.clockwise);
                self.emit(node, coord, &xf, cw, "Coordinate3")?;
            }
            _ => {
                for &(_, c) in &node.children {
                    self.eval1(c, state, depth + 1)?;
                }
            }
        }
        Ok(())
    }

    pub(super) fn eval2(&mut self, id: usize, xf: &DAffine3, depth: usize) -> Result<()> {
        let nodes = self.nodes;
        let node = nodes
            .get(id)
            .ok_or_else(|| Error::invalid(self.path, "internal error: bad node id"))?;
        self.visit(node.line, depth)?;
        match node.kind {
            b"IndexedFaceSet" => {
                let coord = node
                    .children
                    .iter()
                    .find(|(f, _)| *f == Some(b"coord".as_slice()))
                    .or_else(|| {
                        node.children
                            .iter()
                            .find(|(_, c)| nodes.get(*c).is_some_and(|n| n.kind == b"Coordinate"))
                    })
                    .map(|&(_, c)| c);
                self.emit(
                    node,
                    coord,
                    xf,
                    node.clockwise.unwrap_or(false),
                    "Coordinate",
                )?;
            }
            b"Transform" => {
                let inner = *xf * rigid_transform(node);
                for &(_, c) in &node.children {
                    self.eval2(c, &inner, depth + 1)?;
                }
            }
            _ => {
                for &(_, c) in &node.children {
                    self.eval2(c, xf, depth + 1)?;
                }
            }
        }
        Ok(())
    }

    /// Appends one face set: its points (unless this coordinate node was already placed with
    /// this transform) and its faces.
    pub(super) fn emit(
        &mut self,
        ifs: &Node,
        coord: Option<usize>,
        xf: &DAffine3,
        clockwise: bool,
        coord_kind: &str,
    ) -> Result<()> {
        if ifs.coord_index.is_empty() {
            return Ok(());
        }
        let line = ifs.coord_index_line;
        let Some(coord) = coord else {
            return Err(Error::syntax(
                self.path,
                ifs.line,
                format!("IndexedFaceSet has no {coord_kind} to take its points from"),
            ));
        };
        let points_len = self.node(coord)?.points.len();
        let base = match self.placed.iter().find(|(c, x, _)| *c == coord && x == xf) {
            Some(&(_, _, base)) => base,
            None => {
                let base = self.positions.len();
                let limit = self.limits.max_vertices.min(self.budget);
                if base + points_len > limit {
                    return Err(Error::syntax(
                        self.path,
                        line,
                        format!("the scene expands to more than {limit} vertices"),
                    ));
                }
                let nodes = self.nodes;
                let pts = nodes.get(coord).map(|n| n.points.as_slice()).unwrap_or(&[]);
                self.positions
                    .extend(pts.iter().map(|&p| xf.transform_point3(p)));
                let base = base as u32;
                self.placed.push((coord, *xf, base));
                base
            }
        };
        let limit = self.limits.max_vertices.saturating_mul(8).min(self.budget);
        if self.faces.indices.len() + ifs.coord_index.len() > limit {
            return Err(Error::syntax(
                self.path,
                line,
                format!("the scene expands to more than {limit} face corners"),
            ));
        }
        let mut face = std::mem::take(&mut self.scratch);
        face.clear();
        let mut face_no = 0usize;
        let n = ifs.coord_index.len();
        for (k, &i) in ifs.coord_index.iter().enumerate() {
            if i >= 0 {
                if i as u64 >= points_len as u64 {
                    return Err(Error::syntax(
                        self.path,
                        line,
                        format!(
                            "coordIndex face {face_no} refers to point {i}, but the \
                             {coord_kind} has only {points_len} points"
                        ),
                    ));
                }
                face.push(base + i as u32);
            } else if i != -1 {
                return Err(Error::syntax(
                    self.path,
                    line,
                    format!(
                        "coordIndex face {face_no} has the negative index {i} (only -1 separates faces)"
                    ),
                ));
            }
            if i == -1 || k + 1 == n {
                if !face.is_empty() {
                    crate::io::push_clean_face(&mut self.faces, &mut face, clockwise);
                    face_no += 1;
                }
                face.clear();
            }
        }
        self.scratch = face;
        Ok(())
    }
}
