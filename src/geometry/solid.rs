//! Closed triangle meshes as solids: the true surface of a non-convex object (paper 003 §IV-A
//! grasps a statuette between its legs), its inside by winding number, and a conservative box
//! cover for the fast checkers.
//!
//! A mesh is a **solid** when, after welding vertices at equal positions, every undirected edge
//! is used by exactly two triangles in opposite directions (each connected component is closed
//! and consistently oriented). Components turned inside out (negative signed volume) are
//! flipped, so the generalized winding number (the solid angle of all triangles seen from a
//! point over 4π; Jacobson et al., SIGGRAPH 2013) is ≥ 1 inside any component and 0 outside
//! all: overlapping components, as a statuette joined from swept primitives has, make their
//! union. [`Solid::contains`] is `winding > 1/2`.
//!
//! The **cover** is a set of axis-aligned boxes (in the mesh frame) whose union contains the
//! solid, for checkers that only know primitives: the box around the mesh is cut into a grid of
//! cubic cells, [`COVER_CELLS`] along its longest side (fewer when that needs more than
//! [`MAX_COVER_BOXES`] boxes); a cell is kept when a triangle meets it
//! (separating-axis test of triangle and box, the box grown by a round-off margin) or when it
//! cannot be reached from outside the grid through cells no triangle meets (a cell that no
//! triangle meets lies wholly inside or wholly outside, and face neighbours of that kind lie on
//! the same side); the kept cells are merged greedily into boxes. Every point of the cover is in
//! a cell that meets the solid, so the cover protrudes at most one cell diagonal
//! ([`Solid::cover_protrusion`]) beyond it. Robot links get a coarser cover of at most
//! [`MAX_MOVING_COVER_BOXES`] boxes, since their boxes are paired with other moving bodies' and
//! swept by the certified checks; held objects keep the fine cover in the fast checker (a hand
//! comes to within millimetres of them at a hand-over, `src/collision/fast.rs`). Meshes that are not closed have no solid: checkers
//! keep their convex hull (exact) and the box around them (fast), both conservative.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

/// Cells of the cover grid along the longest side of the mesh's box.
pub const COVER_CELLS: usize = 48;

/// Most boxes in a cover: a finer grid that needs more is halved (down to 6 cells a side), so a
/// checker's cost per mesh stays bounded.
pub const MAX_COVER_BOXES: usize = 256;

/// Most boxes in the coarse cover of a moving mesh (a robot link, a held object), whose boxes
/// are paired with other moving bodies' and swept by the certified motion checks: the grid is
/// halved from 24 cells until it fits, else the box around the mesh is used.
pub const MAX_MOVING_COVER_BOXES: usize = 16;

/// An axis-aligned box `(centre, half extents)`.
pub type CoverBox = (Vector3<f64>, Vector3<f64>);

/// A closed, consistently oriented triangle mesh (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Solid {
    /// Welded vertices in the mesh frame.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles, every component oriented outward.
    pub triangles: Vec<[u32; 3]>,
    /// Connected components (after welding).
    pub components: usize,
    /// Boxes `(centre, half extents)` in the mesh frame whose union contains the solid.
    pub cover: Vec<CoverBox>,
    /// Edge of the cover's cells.
    pub cell: f64,
    /// The coarse cover for moving bodies (at most [`MAX_MOVING_COVER_BOXES`] boxes) and a bound
    /// on how far it protrudes beyond the solid.
    pub moving_cover: Vec<CoverBox>,
    pub moving_protrusion: f64,
    /// Per component: the box around its vertices and its triangles (a range of
    /// `component_triangles`, indices into `triangles`), for [`Solid::winding`].
    component_boxes: Vec<(Vector3<f64>, Vector3<f64>, std::ops::Range<usize>)>,
    component_triangles: Vec<u32>,
}

impl Solid {
    /// The solid of a triangle mesh, or why it is not one (not closed, an edge used by more or
    /// fewer than two triangles, inconsistent orientation, no volume).
    pub fn new(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> Result<Solid, String> {
        let n = vertices.len();
        if triangles.is_empty() {
            return Err("no triangles".to_string());
        }
        // Weld vertices at bit-equal positions (loaders split vertices by normal or texture).
        let mut id: HashMap<[u64; 3], u32> = HashMap::new();
        let mut welded: Vec<Point3<f64>> = Vec::new();
        let mut map = Vec::with_capacity(n);
        for v in vertices {
            let key = [v.x, v.y, v.z].map(|c| (c + 0.0).to_bits());
            let k = *id.entry(key).or_insert_with(|| {
                welded.push(*v);
                (welded.len() - 1) as u32
            });
            map.push(k);
        }
        let mut tris: Vec<[u32; 3]> = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            let mut w = [0u32; 3];
            for (k, &i) in tri.iter().enumerate() {
                w[k] = *map.get(i as usize).ok_or_else(|| {
                    format!("triangle {t} uses vertex {i}, the mesh has {n} vertices")
                })?;
            }
            if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
                // Collapsed by welding: no area, no edge of the surface.
                continue;
            }
            tris.push(w);
        }
        if tris.is_empty() {
            return Err("every triangle is degenerate".to_string());
        }
        // Directed edges: each must appear once, its reverse once.
        let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(tris.len() * 3);
        for (t, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let e = (tri[k], tri[(k + 1) % 3]);
                if directed.insert(e, t as u32).is_some() {
                    return Err(format!(
                        "edge {}–{} is used twice in the same direction (not a closed, \
                         consistently oriented surface)",
                        e.0, e.1
                    ));
                }
            }
        }
        for &(a, b) in directed.keys() {
            if !directed.contains_key(&(b, a)) {
                return Err(format!(
                    "edge {a}–{b} borders one triangle only (the surface is not closed)"
                ));
            }
        }
        // Components by shared edges (union–find over triangles).
        let mut parent: Vec<u32> = (0..tris.len() as u32).collect();
        fn find(p: &mut [u32], mut x: u32) -> u32 {
            while p[x as usize] != x {
                let g = p[p[x as usize] as usize];
                p[x as usize] = g;
                x = g;
            }
            x
        }
        for (&(a, b), &t) in &directed {
            if let Some(&u) = directed.get(&(b, a)) {
                let (ra, rb) = (find(&mut parent, t), find(&mut parent, u));
                if ra != rb {
                    parent[ra as usize] = rb;
                }
            }
        }
        let mut volume: HashMap<u32, f64> = HashMap::new();
        for (t, tri) in tris.iter().enumerate() {
            let [a, b, c] = tri.map(|i| welded[i as usize].coords);
            let r = find(&mut parent, t as u32);
            *volume.entry(r).or_insert(0.0) += a.dot(&b.cross(&c)) / 6.0;
        }
        for (t, tri) in tris.iter_mut().enumerate() {
            let r = find(&mut parent, t as u32);
            if volume[&r] < 0.0 {
                tri.swap(1, 2);
            }
        }
        if volume.values().all(|v| v.abs() <= 0.0) {
            return Err("the surface encloses no volume".to_string());
        }
        let components = volume.len();
        // Triangles by component, with the box around each component's vertices.
        let mut by_root: Vec<(u32, u32)> = (0..tris.len() as u32)
            .map(|t| (find(&mut parent, t), t))
            .collect();
        by_root.sort_unstable();
        let component_triangles: Vec<u32> = by_root.iter().map(|&(_, t)| t).collect();
        let mut component_boxes = Vec::with_capacity(components);
        let mut first = 0;
        while first < by_root.len() {
            let root = by_root[first].0;
            let end = first + by_root[first..].partition_point(|&(r, _)| r == root);
            let (mut lo, mut hi) = (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            );
            for &(_, t) in &by_root[first..end] {
                for &i in &tris[t as usize] {
                    lo = lo.inf(&welded[i as usize].coords);
                    hi = hi.sup(&welded[i as usize].coords);
                }
            }
            component_boxes.push((lo, hi, first..end));
            first = end;
        }
        let mut cells = COVER_CELLS;
        let (mut cover, mut cell) = cover(&welded, &tris, cells);
        while cover.len() > MAX_COVER_BOXES && cells > 6 {
            cells /= 2;
            (cover, cell) = self::cover(&welded, &tris, cells);
        }
        let (mut moving_cover, mut moving_protrusion) = (Vec::new(), f64::INFINITY);
        let mut cells = COVER_CELLS / 2;
        while cells >= 3 {
            let (c, h) = self::cover(&welded, &tris, cells);
            if c.len() <= MAX_MOVING_COVER_BOXES {
                (moving_cover, moving_protrusion) = (c, h * 3f64.sqrt());
                break;
            }
            cells /= 2;
        }
        if moving_cover.is_empty() {
            // The box around the vertices: no point of it is farther than its diagonal.
            let (lo, hi) = bounds(&welded);
            moving_cover = vec![((lo + hi) / 2.0, (hi - lo) / 2.0)];
            moving_protrusion = (hi - lo).norm();
        }
        Ok(Solid {
            vertices: welded,
            triangles: tris,
            components,
            cover,
            cell,
            moving_cover,
            moving_protrusion,
            component_boxes,
            component_triangles,
        })
    }

    /// The generalized winding number of `p` (module docs): about 1 inside a component, 0
    /// outside all, summed where components overlap. A component whose box does not hold `p`
    /// is left out: a closed surface's winding number is 0 outside it (exactly; summed over
    /// its triangles it would add only round-off).
    pub fn winding(&self, p: &Vector3<f64>) -> f64 {
        let mut sum = 0.0;
        let tris = self
            .component_boxes
            .iter()
            .filter(|(lo, hi, _)| (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k]))
            .flat_map(|(_, _, r)| &self.component_triangles[r.clone()]);
        for &t in tris {
            let [a, b, c] =
                self.triangles[t as usize].map(|i| self.vertices[i as usize].coords - p);
            let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
            // Van Oosterom & Strackee (1983): the solid angle of a triangle.
            let num = a.dot(&b.cross(&c));
            let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
            sum += 2.0 * num.atan2(den);
        }
        sum / (4.0 * std::f64::consts::PI)
    }

    /// Per connected component: the box `(lo, hi)` around its vertices (mesh frame).
    pub fn component_bounds(&self) -> impl Iterator<Item = (Vector3<f64>, Vector3<f64>)> + '_ {
        self.component_boxes.iter().map(|(lo, hi, _)| (*lo, *hi))
    }

    /// True when `p` (mesh frame) is inside the solid; points outside the cover answer at
    /// once.
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        let in_cover = self
            .cover
            .iter()
            .any(|(c, h)| (p - c).abs().iter().zip(h.iter()).all(|(d, h)| *d <= *h));
        in_cover && self.winding(p) > 0.5
    }

    /// The farthest any point of the cover can be from the solid: one cell diagonal.
    pub fn cover_protrusion(&self) -> f64 {
        self.cell * 3f64.sqrt()
    }
}

/// The box `(lo, hi)` around the vertices.
fn bounds(vertices: &[Point3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    vertices.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), v| (lo.inf(&v.coords), hi.sup(&v.coords)),
    )
}

/// The cover boxes and the cell edge (module docs); each box is clipped to the box around the
/// vertices, which holds the solid.
fn cover(vertices: &[Point3<f64>], tris: &[[u32; 3]], cells: usize) -> (Vec<CoverBox>, f64) {
    let (lo, hi) = bounds(vertices);
    let ext = hi - lo;
    let longest = ext.max();
    let cell = if longest > 0.0 {
        longest / cells as f64
    } else {
        1e-9
    };
    // One empty cell of padding on every side: the flood fill starts there.
    let dims: [usize; 3] = [0, 1, 2].map(|k| ((ext[k] / cell).ceil() as usize).max(1) + 2);
    let origin = lo - Vector3::repeat(cell);
    let idx = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
    let total = dims[0] * dims[1] * dims[2];
    let mut surface = vec![false; total];
    let margin = cell * 1e-9 + longest * 1e-12;
    let half = Vector3::repeat(cell / 2.0 + margin);
    for t in tris {
        let [a, b, c] = t.map(|i| vertices[i as usize].coords);
        let tlo = a.inf(&b).inf(&c);
        let thi = a.sup(&b).sup(&c);
        let range = |k: usize| {
            let l =
                (((tlo[k] - margin - origin[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1);
            let h =
                (((thi[k] + margin - origin[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1);
            l..=h
        };
        let (ri, rj, rk) = (range(0), range(1), range(2));
        for k in rk {
            for j in rj.clone() {
                for i in ri.clone() {
                    let centre = origin
                        + Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * cell;
                    if triangle_box_overlap(&(a - centre), &(b - centre), &(c - centre), &half) {
                        surface[idx(i, j, k)] = true;
                    }
                }
            }
        }
    }
    // Flood fill the outside from the padding corner through cells no triangle meets.
    let mut outside = vec![false; total];
    let mut stack = vec![(0usize, 0usize, 0usize)];
    outside[0] = true;
    while let Some((i, j, k)) = stack.pop() {
        let mut visit = |i: usize, j: usize, k: usize| {
            let c = idx(i, j, k);
            if !outside[c] && !surface[c] {
                outside[c] = true;
                stack.push((i, j, k));
            }
        };
        if i > 0 {
            visit(i - 1, j, k);
        }
        if i + 1 < dims[0] {
            visit(i + 1, j, k);
        }
        if j > 0 {
            visit(i, j - 1, k);
        }
        if j + 1 < dims[1] {
            visit(i, j + 1, k);
        }
        if k > 0 {
            visit(i, j, k - 1);
        }
        if k + 1 < dims[2] {
            visit(i, j, k + 1);
        }
    }
    // Greedy merge of the kept cells into boxes: x runs, then rows, then slabs.
    let mut used: Vec<bool> = outside;
    let mut boxes = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                if used[idx(i, j, k)] {
                    continue;
                }
                let mut i1 = i + 1;
                while i1 < dims[0] && !used[idx(i1, j, k)] {
                    i1 += 1;
                }
                let row_free =
                    |j: usize, k: usize, used: &[bool]| (i..i1).all(|x| !used[idx(x, j, k)]);
                let mut j1 = j + 1;
                while j1 < dims[1] && row_free(j1, k, &used) {
                    j1 += 1;
                }
                let mut k1 = k + 1;
                while k1 < dims[2] && (j..j1).all(|y| row_free(y, k1, &used)) {
                    k1 += 1;
                }
                for z in k..k1 {
                    for y in j..j1 {
                        for x in i..i1 {
                            used[idx(x, y, z)] = true;
                        }
                    }
                }
                // Clipped to the vertices' box, grown by the round-off margin.
                let blo = (origin + Vector3::new(i as f64, j as f64, k as f64) * cell)
                    .sup(&lo.add_scalar(-margin));
                let bhi = (origin + Vector3::new(i1 as f64, j1 as f64, k1 as f64) * cell)
                    .inf(&hi.add_scalar(margin));
                boxes.push(((blo + bhi) / 2.0, (bhi - blo) / 2.0));
            }
        }
    }
    (boxes, cell)
}

/// Separating-axis test of a triangle (vertices relative to the box centre) against an
/// axis-aligned box of half extents `h` (Akenine-Möller 2001): true when they may overlap,
/// exactly up to round-off.
fn triangle_box_overlap(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
    h: &Vector3<f64>,
) -> bool {
    // The box's face normals.
    for k in 0..3 {
        let lo = a[k].min(b[k]).min(c[k]);
        let hi = a[k].max(b[k]).max(c[k]);
        if lo > h[k] || hi < -h[k] {
            return false;
        }
    }
    // The triangle's normal.
    let n = (b - a).cross(&(c - a));
    let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
    let s = n.dot(a);
    if s > r || s < -r {
        return false;
    }
    // Edge × axis.
    let edges = [b - a, c - b, a - c];
    for e in &edges {
        for k in 0..3 {
            let mut axis = Vector3::zeros();
            axis[k] = 1.0;
            let l = e.cross(&axis);
            if l.norm_squared() == 0.0 {
                continue;
            }
            let (pa, pb, pc) = (l.dot(a), l.dot(b), l.dot(c));
            let r = h.x * l.x.abs() + h.y * l.y.abs() + h.z * l.z.abs();
            if pa.min(pb).min(pc) > r || pa.max(pb).max(pc) < -r {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box as 12 triangles (outward), optionally with each face's vertices split.
    fn cube(c: Vector3<f64>, h: f64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let mut v = Vec::new();
        for k in 0..8 {
            let s = |b: usize| if k & b != 0 { h } else { -h };
            v.push(Point3::from(c + Vector3::new(s(1), s(2), s(4))));
        }
        let faces = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let mut t = Vec::new();
        for f in faces {
            t.push([f[0], f[1], f[2]]);
            t.push([f[0], f[2], f[3]]);
        }
        (v, t)
    }

    #[test]
    fn cube_is_a_solid_with_winding_one_inside() {
        let (v, t) = cube(Vector3::zeros(), 0.5);
        let s = Solid::new(&v, &t).unwrap();
        assert_eq!(s.components, 1);
        assert!((s.winding(&Vector3::new(0.1, -0.2, 0.3)) - 1.0).abs() < 1e-9);
        assert!(s.winding(&Vector3::new(0.7, 0.0, 0.0)).abs() < 1e-9);
        assert!(s.contains(&Vector3::new(0.49, 0.49, -0.49)));
        assert!(!s.contains(&Vector3::new(0.51, 0.0, 0.0)));
        // The cover holds the cube and protrudes at most a cell diagonal.
        let (lo, hi) = s.cover.iter().fold(
            (Vector3::repeat(9.0), Vector3::repeat(-9.0)),
            |(lo, hi), (c, h)| (lo.inf(&(c - h)), hi.sup(&(c + h))),
        );
        for k in 0..3 {
            assert!(lo[k] <= -0.5 && hi[k] >= 0.5);
            assert!(lo[k] >= -0.5 - s.cover_protrusion() && hi[k] <= 0.5 + s.cover_protrusion());
        }
    }

    #[test]
    fn inside_out_components_are_flipped_and_union_is_inside() {
        let (mut v, mut t) = cube(Vector3::zeros(), 0.5);
        let (v2, t2) = cube(Vector3::new(0.6, 0.0, 0.0), 0.3);
        let base = v.len() as u32;
        v.extend(v2);
        // The second cube inside out.
        t.extend(t2.iter().map(|f| [f[0] + base, f[2] + base, f[1] + base]));
        let s = Solid::new(&v, &t).unwrap();
        assert_eq!(s.components, 2);
        assert!(s.contains(&Vector3::new(0.8, 0.0, 0.0)));
        assert!(s.contains(&Vector3::new(0.45, 0.0, 0.0)));
        assert!(!s.contains(&Vector3::new(0.8, 0.4, 0.0)));
    }

    #[test]
    fn open_or_inconsistent_surfaces_are_refused() {
        let (v, t) = cube(Vector3::zeros(), 0.5);
        let open = &t[..11];
        assert!(Solid::new(&v, open).unwrap_err().contains("not closed"));
        let mut flipped = t.clone();
        flipped[0].swap(1, 2);
        assert!(Solid::new(&v, &flipped).is_err());
        assert!(Solid::new(&v, &[[0, 1, 99]])
            .unwrap_err()
            .contains("vertex 99"));
    }

    #[test]
    fn split_vertices_are_welded() {
        let (v, t) = cube(Vector3::zeros(), 0.5);
        // Every triangle with its own three vertices, as OBJ loaders with normals give.
        let mut v2 = Vec::new();
        let mut t2 = Vec::new();
        for f in &t {
            let b = v2.len() as u32;
            v2.extend(f.iter().map(|&i| v[i as usize]));
            t2.push([b, b + 1, b + 2]);
        }
        let s = Solid::new(&v2, &t2).unwrap();
        assert_eq!(s.vertices.len(), 8);
    }
}
