//! Garments from flat panels sewn together (`[cloth.garment]`).
//!
//! A garment is made the way a tailor (or Marvelous Designer, CLO, GarmentCode) makes one:
//! flat pattern panels, each a 2-D outline in metres with optional holes and named edges, are
//! placed around a body and sewn along seams. Here that compiles, when the scene is read, into
//! a mesh cloth ([`crate::mesh_cloth`]) with one more family of springs, the seams:
//!
//! 1. Every seam pairs two named edges (boundary chains, runs of outline points). Both chains
//!    are sampled at one set of arc-length parameters: every corner of either chain (each
//!    chain gets the other's corners as extra points) and `ceil(L / edge_length)` even steps,
//!    `L` the longer chain, so the two get the same number of points and point `k` of one is
//!    sewn to point `k` of the other counted from its far end: two panels joined into one
//!    surface that faces one way run along their seam in opposite directions, as neighbouring
//!    triangles do along their edge (`reverse = true` sews start to start, for a panel turned
//!    over). Picking the way by distance fails on symmetric layouts: a shirt's front and
//!    back laid out flat have their side seams' ends equally far apart either way, and the
//!    seam sewn hem to armpit twisted the shirt. Chains whose lengths differ by more than
//!    [`MAX_LENGTH_RATIO`] are refused: sewing them would gather one side.
//! 2. Each panel's boundary is its outline with those seam points on the seamed edges and even
//!    points of about the edge length on the others; spade's constrained Delaunay
//!    triangulation meshes the inside with Ruppert refinement (triangles of at most an
//!    equilateral triangle's area at the edge length, no angle under 25 degrees) and never
//!    splits the boundary, so the seam points stay exactly as paired.
//! 3. The flat mesh is placed: `p = origin + u x_axis + v y_axis`, or wrapped on a cylinder of
//!    `wrap_radius` whose axis is `y_axis` and runs `wrap_radius` behind the panel (the panel
//!    touches it at `u = 0`, arc length `u` round it). UVs are the flat coordinates in m.
//! 4. The seams become springs (kind `Seam`) from each point to its partner, whose rest length
//!    goes from the pair's starting distance to zero over `sew_time` seconds and then stays
//!    zero: the panels are drawn together at a bounded speed, instead of being snapped by a
//!    zero-length spring stretched across the whole gap from the start.
//!
//! Pairs that start closed (chains laid out on each other, like a shirt's shoulders when its
//! front and back lie flat side by side) are merged into one vertex when the garment is built:
//! nothing is left to pull, and the cloth's own springs then run across the seam.
//!
//! Why springs and not merging the vertices once the gap closes: merging renumbers the
//! particles while the simulation runs (vertex `k` is particle `k` for pins, snapshots,
//! export and every array the binding hands out), and a spring of zero rest length with the
//! stiffness of the cloth's own edges holds the seam to well under a millimetre (measured in
//! docs/garments.md).

mod outline;
mod spec;
mod triangulate;

use std::collections::BTreeMap;

use glam::{DVec2, DVec3};

use crate::error::{check_scalar, check_vector, Bound, Error, Result};
use serde::{Deserialize, Serialize};
pub use spec::{GarmentSpec, PanelSpec, Placement, SeamSpec};

use outline::{
    chain_corners, check_polygon, corner_parameters, first_crossing, length, point_at, signed_area2,
};

/// Where a scene keeps the garment, for error names.
const AT: &str = "cloth.garment";

/// Two chains sewn together may differ in length by at most this factor.
pub const MAX_LENGTH_RATIO: f64 = 1.5;

/// A compiled garment: a mesh cloth's vertices, triangles and UVs, the vertex pairs sewn
/// (pairs that start closed are merged into one vertex instead), and each triangle on its flat
/// panel.
#[derive(Clone, Debug, PartialEq)]
pub struct Garment {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[i64; 3]>,
    pub uvs: Vec<[f64; 2]>,
    pub seams: Vec<[i64; 2]>,
    pub panels: FlatPanels,
}

/// Each triangle of a garment on its flat panel: the panel and its three corners there, in m
/// in the panel's own 2-D layout. Per corner rather than per vertex because a vertex merged
/// across a seam that started closed has a place on each of its panels.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlatPanels {
    /// Per triangle, the index of its panel.
    pub panel: Vec<u32>,
    /// Per triangle, its corners on its panel (m).
    pub corners: Vec<[[f64; 2]; 3]>,
}

/// A checked panel: its outline, holes and placement.
struct Panel {
    outline: Vec<DVec2>,
    holes: Vec<Vec<DVec2>>,
    place: Box<dyn Fn(DVec2) -> DVec3>,
}

/// One side of a seam: a panel and the outline points `start..=end` of its named edge.
#[derive(Clone, Copy)]
struct Chain {
    panel: usize,
    start: usize,
    end: usize,
}

impl GarmentSpec {
    /// Checks the garment and builds its mesh and seams. Errors name `cloth.garment.<key>`:
    /// a self-intersecting or zero-area outline, a hole outside it, an edge whose points are
    /// not on the outline, a seam naming an unknown edge, two seams sharing a side, chains
    /// whose lengths differ by more than [`MAX_LENGTH_RATIO`].
    pub fn compile(&self) -> Result<Garment> {
        check_scalar(
            &format!("{AT}.edge_length"),
            self.edge_length,
            Bound::Positive,
        )?;
        check_scalar(&format!("{AT}.sew_time"), self.sew_time, Bound::Positive)?;
        check_scalar(
            &format!("{AT}.seam_stiffness"),
            self.seam_stiffness,
            Bound::Positive,
        )?;
        check_scalar(
            &format!("{AT}.seam_damping"),
            self.seam_damping,
            Bound::NonNegative,
        )?;
        if self.panels.is_empty() {
            return Err(Error::value(
                format!("{AT}.panels"),
                "a garment needs at least one panel",
            ));
        }
        let h = self.edge_length;
        let panels = self
            .panels
            .iter()
            .enumerate()
            .map(|(p, spec)| check_panel(p, spec, h, &self.panels[..p]))
            .collect::<Result<Vec<_>>>()?;
        let chains = self
            .seams
            .iter()
            .enumerate()
            .map(|(s, seam)| {
                Ok([
                    find_chain(&self.panels, &format!("{AT}.seams[{s}].a"), &seam.a)?,
                    find_chain(&self.panels, &format!("{AT}.seams[{s}].b"), &seam.b)?,
                ])
            })
            .collect::<Result<Vec<_>>>()?;
        // No side of an outline in two seams.
        let mut owner: BTreeMap<(usize, usize), usize> = BTreeMap::new();
        for (s, pair) in chains.iter().enumerate() {
            for (side, c) in pair.iter().enumerate() {
                let n = panels[c.panel].outline.len();
                let mut i = c.start;
                while i != c.end {
                    if let Some(other) = owner.insert((c.panel, i), s) {
                        let key = if side == 0 { "a" } else { "b" };
                        return Err(Error::value(
                            format!("{AT}.seams[{s}].{key}"),
                            format!(
                                "side {i} of panel {:?} is already sewn by seams[{other}]: a \
                                 side can be in one seam only",
                                self.panels[c.panel].name
                            ),
                        ));
                    }
                    i = (i + 1) % n;
                }
            }
        }
        // The parameters each seam is sampled at, and which way its second chain runs.
        let mut samples: Vec<(Vec<f64>, bool)> = Vec::with_capacity(chains.len());
        for (s, [a, b]) in chains.iter().enumerate() {
            let pa = chain_corners(&panels[a.panel].outline, a.start, a.end);
            let pb = chain_corners(&panels[b.panel].outline, b.start, b.end);
            let (la, lb) = (length(&pa), length(&pb));
            if la.max(lb) > MAX_LENGTH_RATIO * la.min(lb) {
                return Err(Error::value(
                    format!("{AT}.seams[{s}]"),
                    format!(
                        "its chains differ too much in length: {:?} is {la:.4} m, {:?} is \
                         {lb:.4} m (at most {MAX_LENGTH_RATIO} times apart); sewing them would \
                         gather the longer one",
                        self.seams[s].a, self.seams[s].b
                    ),
                ));
            }
            // Two panels joined into one consistently facing surface run along their seam in
            // opposite directions (as two neighbouring triangles run along their shared edge),
            // each outline taken counter-clockwise: a's start meets b's end.
            let ccw = |c: &Chain| signed_area2(&panels[c.panel].outline) > 0.0;
            let reversed = (ccw(a) == ccw(b)) != self.seams[s].reverse;
            let steps = (la.max(lb) / h).ceil().max(1.0) as usize;
            let mut ts: Vec<f64> = (0..=steps).map(|k| k as f64 / steps as f64).collect();
            let corners_b =
                corner_parameters(&pb)
                    .into_iter()
                    .map(|t| if reversed { 1.0 - t } else { t });
            let corners: Vec<f64> = corner_parameters(&pa)
                .into_iter()
                .chain(corners_b)
                .collect();
            // A corner replaces the even step nearest it when closer than a third of a step.
            for &t in &corners {
                let k = ts
                    .iter()
                    .enumerate()
                    .min_by(|x, y| (x.1 - t).abs().total_cmp(&(y.1 - t).abs()))
                    .map(|(k, _)| k)
                    .expect("at least two steps");
                if (ts[k] - t).abs() < 1.0 / (3.0 * steps as f64) {
                    if k != 0 && k != steps {
                        ts[k] = t;
                    }
                } else {
                    ts.push(t);
                }
            }
            ts.sort_by(f64::total_cmp);
            ts.dedup_by(|x, y| (*x - *y).abs() < 1e-12);
            samples.push((ts, reversed));
        }
        // Each panel's boundary ring, meshed and placed.
        let mut out = Garment {
            vertices: Vec::new(),
            triangles: Vec::new(),
            uvs: Vec::new(),
            seams: Vec::new(),
            panels: FlatPanels::default(),
        };
        // For each seam side, the global vertex of each sample.
        let mut sewn: Vec<[Vec<i64>; 2]> = vec![[Vec::new(), Vec::new()]; chains.len()];
        for (p, panel) in panels.iter().enumerate() {
            let name = format!("{AT}.panels[{p}]");
            let mut starts: BTreeMap<usize, (usize, usize)> = BTreeMap::new();
            for (s, pair) in chains.iter().enumerate() {
                for (side, c) in pair.iter().enumerate() {
                    if c.panel == p {
                        starts.insert(c.start, (s, side));
                    }
                }
            }
            let (ring, marks) = boundary_ring(panel, &starts, &chains, &samples, h);
            let holes: Vec<Vec<DVec2>> = panel.holes.iter().map(|hole| resample(hole, h)).collect();
            let flat = triangulate::triangulate(&name, &ring, &holes, h)?;
            let base = out.vertices.len() as i64;
            for (s, side, k, at) in marks {
                let slot = &mut sewn[s][side];
                if slot.len() <= k {
                    slot.resize(k + 1, -1);
                }
                slot[k] = base + at as i64;
            }
            for &q in &flat.points {
                out.vertices.push((panel.place)(q).to_array());
                out.uvs.push(q.to_array());
            }
            out.triangles
                .extend(flat.triangles.iter().map(|t| t.map(|v| base + v as i64)));
            for t in &flat.triangles {
                out.panels.panel.push(p as u32);
                (out.panels.corners).push(t.map(|v| flat.points[v as usize].to_array()));
            }
        }
        for (s, [a, b]) in sewn.iter().enumerate() {
            let reversed = samples[s].1;
            let n = a.len();
            debug_assert_eq!(n, b.len());
            for k in 0..n {
                let partner = if reversed { b[n - 1 - k] } else { b[k] };
                if a[k] != partner {
                    out.seams.push([a[k], partner]);
                }
            }
        }
        Ok(merge_closed(out))
    }
}

/// Two sewn points this close (m) once placed are one point.
const CLOSED: f64 = 1e-9;

/// Merges each sewn pair that starts closed (the two chains already lie on each other once
/// placed) into one vertex, the lower index, and renumbers the rest in order: there is nothing
/// for a seam spring to pull, and a merged seam has the cloth's own stretch and bend springs
/// across it, where a zero-length spring between two light corner vertices was the stiffest
/// thing in the shirt (its stable step a third of the cloth's). The other pairs stay seams,
/// sorted, each once.
fn merge_closed(mut garment: Garment) -> Garment {
    let n = garment.vertices.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    let at = |k: i64| DVec3::from(garment.vertices[k as usize]);
    for &[a, b] in &garment.seams {
        if at(a).distance(at(b)) <= CLOSED {
            let (ra, rb) = (root(&mut parent, a as usize), root(&mut parent, b as usize));
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    let mut index = vec![0i64; n];
    let mut kept = 0;
    for v in 0..n {
        let r = root(&mut parent, v);
        if r == v {
            index[v] = kept;
            kept += 1;
        } else {
            index[v] = index[r];
        }
    }
    let keep = |v: usize| parent[v] == v;
    garment.vertices = (0..n)
        .filter(|&v| keep(v))
        .map(|v| garment.vertices[v])
        .collect();
    garment.uvs = (0..n)
        .filter(|&v| keep(v))
        .map(|v| garment.uvs[v])
        .collect();
    for t in &mut garment.triangles {
        *t = t.map(|v| index[v as usize]);
    }
    let mut seams: Vec<[i64; 2]> = garment
        .seams
        .iter()
        .map(|&[a, b]| [index[a as usize], index[b as usize]])
        .filter(|&[a, b]| a != b)
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    seams.sort_unstable();
    seams.dedup();
    garment.seams = seams;
    garment
}

/// Checks panel `p` and turns its placement into a function of the flat point.
fn check_panel(p: usize, spec: &PanelSpec, h: f64, before: &[PanelSpec]) -> Result<Panel> {
    let at = format!("{AT}.panels[{p}]");
    if spec.name.is_empty() || spec.name.contains('.') {
        return Err(Error::value(
            format!("{at}.name"),
            format!("must be a non-empty name without '.', got {:?}", spec.name),
        ));
    }
    if let Some(q) = before.iter().position(|o| o.name == spec.name) {
        return Err(Error::value(
            format!("{at}.name"),
            format!("{:?} is also the name of panels[{q}]", spec.name),
        ));
    }
    let outline = check_polygon(&format!("{at}.outline"), &spec.outline, h)?;
    let mut holes = Vec::with_capacity(spec.holes.len());
    for (k, hole) in spec.holes.iter().enumerate() {
        let ring = check_polygon(&format!("{at}.holes[{k}]"), hole, h)?;
        if first_crossing(&outline, &ring, false).is_some() {
            return Err(Error::value(
                format!("{at}.holes[{k}]"),
                "crosses the outline: a hole must lie inside it",
            ));
        }
        holes.push(ring);
    }
    for (edge, &[start, end]) in &spec.edges {
        let n = outline.len() as i64;
        for (which, i) in [("start", start), ("end", end)] {
            if !(0..n).contains(&i) {
                return Err(Error::value(
                    format!("{at}.edges.{edge}"),
                    format!(
                        "its {which} {i} is not a point of the outline (which has {n}): a seam's \
                         chain must run along the panel's boundary"
                    ),
                ));
            }
        }
        if start == end {
            return Err(Error::value(
                format!("{at}.edges.{edge}"),
                format!("starts and ends at outline point {start}: an edge needs two points"),
            ));
        }
    }
    let place = placement(&format!("{at}.placement"), &spec.placement)?;
    Ok(Panel {
        outline,
        holes,
        place,
    })
}

fn placement(at: &str, spec: &Placement) -> Result<Box<dyn Fn(DVec2) -> DVec3>> {
    check_vector(&format!("{at}.origin"), &spec.origin, Bound::Any)?;
    check_vector(&format!("{at}.x_axis"), &spec.x_axis, Bound::Any)?;
    check_vector(&format!("{at}.y_axis"), &spec.y_axis, Bound::Any)?;
    let origin = DVec3::from(spec.origin);
    let e1 = DVec3::from(spec.x_axis)
        .try_normalize()
        .ok_or_else(|| Error::value(format!("{at}.x_axis"), "must not be zero"))?;
    let y = DVec3::from(spec.y_axis);
    let e2 = (y - e1 * y.dot(e1)).try_normalize().ok_or_else(|| {
        Error::value(
            format!("{at}.y_axis"),
            "must not be zero or parallel to x_axis",
        )
    })?;
    let n = e1.cross(e2);
    Ok(match spec.wrap_radius {
        None => Box::new(move |q: DVec2| origin + q.x * e1 + q.y * e2),
        Some(r) => {
            check_scalar(&format!("{at}.wrap_radius"), r, Bound::Positive)?;
            let centre = origin - r * n;
            Box::new(move |q: DVec2| {
                let angle = q.x / r;
                centre + r * angle.sin() * e1 + q.y * e2 + r * angle.cos() * n
            })
        }
    })
}

/// The chain a seam names, `"panel.edge"`.
fn find_chain(panels: &[PanelSpec], at: &str, name: &str) -> Result<Chain> {
    let unknown = || {
        let known: Vec<String> = panels
            .iter()
            .flat_map(|p| p.edges.keys().map(move |e| format!("{}.{e}", p.name)))
            .collect();
        Error::value(
            at,
            format!("{name:?} is not a panel's named edge; the edges are {known:?}"),
        )
    };
    let (panel, edge) = name.split_once('.').ok_or_else(unknown)?;
    let p = panels
        .iter()
        .position(|p| p.name == panel)
        .ok_or_else(unknown)?;
    let &[start, end] = panels[p].edges.get(edge).ok_or_else(unknown)?;
    Ok(Chain {
        panel: p,
        start: start as usize,
        end: end as usize,
    })
}

/// Even points of about `h` round a closed polygon, its corners kept.
fn resample(ring: &[DVec2], h: f64) -> Vec<DVec2> {
    let n = ring.len();
    let mut out = Vec::new();
    for i in 0..n {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        let steps = (p.distance(q) / h).ceil().max(1.0) as usize;
        out.extend((0..steps).map(|k| p + (q - p) * (k as f64 / steps as f64)));
    }
    out
}

/// A seam point on a boundary ring: `(seam, side, sample, ring index)`.
type SeamPoint = (usize, usize, usize, usize);

/// A panel's boundary ring: its outline with each seamed chain sampled at its seam's
/// parameters and every other side at even points of about `h`. Also, for each seam point,
/// `(seam, side, sample, ring index)`.
fn boundary_ring(
    panel: &Panel,
    starts: &BTreeMap<usize, (usize, usize)>,
    chains: &[[Chain; 2]],
    samples: &[(Vec<f64>, bool)],
    h: f64,
) -> (Vec<DVec2>, Vec<SeamPoint>) {
    let outline = &panel.outline;
    let n = outline.len();
    // Start at a chain's first point (never inside a chain), or at point 0.
    let first = starts.keys().next().copied().unwrap_or(0);
    let mut ring = Vec::new();
    let mut marks = Vec::new();
    // A chain that ended at the point the walk reaches next: (seam, side, its last sample).
    let mut pending: Option<(usize, usize, usize)> = None;
    let mut i = first;
    let mut walked = 0;
    while walked < n {
        if let Some((s, side, k)) = pending.take() {
            marks.push((s, side, k, ring.len()));
        }
        if let Some(&(s, side)) = starts.get(&i) {
            let c = chains[s][side];
            let corners = chain_corners(outline, c.start, c.end);
            let (ts, reversed) = &samples[s];
            let m = ts.len();
            for k in 0..m - 1 {
                // A reversed seam's second chain meets the first's parameters from its end:
                // its sample k is the first chain's sample m - 1 - k.
                let t = if side == 1 && *reversed {
                    1.0 - ts[m - 1 - k]
                } else {
                    ts[k]
                };
                marks.push((s, side, k, ring.len()));
                ring.push(point_at(&corners, t));
            }
            pending = Some((s, side, m - 1));
            let span = (c.end + n - c.start) % n;
            walked += span;
            i = c.end;
        } else {
            let (p, q) = (outline[i], outline[(i + 1) % n]);
            let steps = (p.distance(q) / h).ceil().max(1.0) as usize;
            ring.extend((0..steps).map(|k| p + (q - p) * (k as f64 / steps as f64)));
            walked += 1;
            i = (i + 1) % n;
        }
    }
    if let Some((s, side, k)) = pending {
        marks.push((s, side, k, 0));
    }
    (ring, marks)
}
