//! A mesh cloth from its [`MeshSpec`]: the checks that refuse a bad mesh (each error names the
//! parameter and the offending vertex or triangle), then the lumped masses and the springs.
//! The model and its equations: [`crate::mesh_cloth`].

use std::collections::HashMap;

use glam::DVec3;

use super::mesh::{check_indices, has_zero_area};
use super::Membrane;
use super::{ClothSpec, IncidenceLanes, MeshSpec, SeamsSpec};
use crate::error::{check_scalar, check_vector, Bound, Error, Result};

/// Two vertices closer than this (m) are one point.
const DEGENERATE: f64 = f32::EPSILON as f64;

/// Where a scene keeps the mesh, for error names.
const AT: &str = "cloth.mesh";

/// What a spring of a mesh cloth stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EdgeKind {
    /// On an edge of the mesh.
    Stretch,
    /// Across an interior edge, between the two opposite vertices.
    Bend,
    /// A seam: two vertices sewn together. Its listed rest length is the pair's starting
    /// distance, scaled down to zero over the cloth's `sew_time` ([`MeshCloth::sewing`]).
    Seam,
}

/// The springs of a mesh cloth as an explicit list, sorted by kind, then by their ends in the
/// mesh's local order (the vertex numbering, or [`LocalNumbering`]'s where that is scattered).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EdgeSprings {
    /// First end (the lower vertex index).
    pub a: Vec<u32>,
    /// Second end.
    pub b: Vec<u32>,
    /// Rest length in m.
    pub rest: Vec<f32>,
    /// Stiffness in N/m.
    pub k: Vec<f32>,
    /// Damping along the spring in N s/m.
    pub c: Vec<f32>,
    pub kind: Vec<EdgeKind>,
    /// Whether the spring holds: false once a cut or a tear severed it, and then its `k` and
    /// `c` are 0 ([`crate::mesh_cloth::topology`]).
    pub active: Vec<bool>,
}

impl EdgeSprings {
    pub fn len(&self) -> usize {
        self.a.len()
    }

    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    fn push(&mut self, (a, b): (u32, u32), rest: f64, k: f64, c: f64, kind: EdgeKind) {
        self.a.push(a.min(b));
        self.b.push(a.max(b));
        self.rest.push(rest as f32);
        self.k.push(k as f32);
        self.c.push(c as f32);
        self.kind.push(kind);
        self.active.push(true);
    }

    /// Spring `e`'s rest length when the seams are at `sewing` of their starting length
    /// ([`MeshCloth::sewing`]), or None when it is a seam that is slack at length `l`: a seam is
    /// a thread, it pulls its ends together and never pushes them apart. The force pass applies
    /// the same rule, written for the vector unit.
    #[inline]
    pub fn taut_rest(&self, e: usize, l: f32, sewing: f32) -> Option<f32> {
        match self.kind[e] {
            EdgeKind::Seam => Some(self.rest[e] * sewing).filter(|&rest| l > rest),
            _ => Some(self.rest[e]),
        }
    }

    /// Lists the springs by kind, then by their ends' places in `rank` (each vertex's place in
    /// a local order; lower first, then higher), ties in their present order. Each spring's
    /// ends stay as they are, the lower vertex index first.
    fn sort_along(&mut self, rank: &[u32]) {
        let kind = |k: EdgeKind| match k {
            EdgeKind::Stretch => 0,
            EdgeKind::Bend => 1,
            EdgeKind::Seam => 2,
        };
        let key = |e: usize| {
            let (a, b) = (rank[self.a[e] as usize], rank[self.b[e] as usize]);
            (kind(self.kind[e]), a.min(b), a.max(b))
        };
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by_key(|&e| key(e));
        fn take<T: Copy>(v: &mut Vec<T>, order: &[usize]) {
            *v = order.iter().map(|&e| v[e]).collect();
        }
        take(&mut self.a, &order);
        take(&mut self.b, &order);
        take(&mut self.rest, &order);
        take(&mut self.k, &order);
        take(&mut self.c, &order);
        take(&mut self.kind, &order);
        take(&mut self.active, &order);
    }

    pub fn heap_bytes(&self) -> usize {
        self.a.capacity() * 4
            + self.b.capacity() * 4
            + self.rest.capacity() * 4
            + self.k.capacity() * 4
            + self.c.capacity() * 4
            + self.kind.capacity() * size_of::<EdgeKind>()
            + self.active.capacity()
    }
}

/// A validated mesh cloth: rest shape, triangles, lumped masses, springs, and for each vertex
/// the springs that touch it (the gather the force pass walks).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshCloth {
    /// Rest (and starting) positions in m, vertex `k` being particle `k`.
    pub rest: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates per vertex, when the mesh has them.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Lumped mass of each vertex in kg.
    pub masses: Vec<f64>,
    pub springs: EdgeSprings,
    /// The springs touching vertex `v` are `incident[offsets[v]..offsets[v + 1]]`, in
    /// increasing order, each as `spring << 1 | end` (`end` 1 at the spring's `b`).
    pub offsets: Vec<u32>,
    pub incident: Vec<u32>,
    /// The same lists in groups of vertices, for the force pass's vector unit.
    pub lanes: IncidenceLanes,
    /// The force pass's own numbering where the vertices' is scattered ([`LocalNumbering`]).
    pub local: Option<LocalNumbering>,
    /// The mean length of the mesh's edges at rest (m): its spacing, where the grid has one.
    pub mean_edge: f64,
    /// Seconds over which the seams close (0 without seams).
    pub sew_time: f64,
    /// The triangle elements of `membrane = "triangle"`, which then hold the stretch and
    /// shear (the stretch springs keep only their damping); None with `"springs"`.
    pub membrane: Option<Membrane>,
}

impl MeshCloth {
    /// Checks `spec` and builds the cloth. Refused, naming `cloth.mesh.<key>[k]`: fewer than
    /// three vertices, a vertex that is not finite or beyond float32, a vertex no triangle
    /// uses, no triangles, an index out of range, a triangle of zero area, a triangle given
    /// twice (in any order), an edge of more than two triangles (non-manifold), two triangles
    /// that run their shared edge the same way (inconsistent winding), `uvs` of the wrong
    /// length or not finite, and a material value out of range.
    pub fn new(spec: &MeshSpec) -> Result<MeshCloth> {
        let rest = &spec.vertices;
        let n = rest.len();
        if n < 3 {
            return Err(Error::value(
                format!("{AT}.vertices"),
                format!("must hold at least 3 vertices, got {n}"),
            ));
        }
        if n > super::MAX_PARTICLES {
            return Err(Error::value(
                format!("{AT}.vertices"),
                format!(
                    "must hold at most {} vertices, got {n}",
                    super::MAX_PARTICLES
                ),
            ));
        }
        for (k, v) in rest.iter().enumerate() {
            let name = format!("{AT}.vertices[{k}]");
            check_vector(&name, v, Bound::Any)?;
            if v.iter().any(|x| !(*x as f32).is_finite()) {
                return Err(Error::value(
                    name,
                    format!("{v:?} is beyond float32 range (3.4e38)"),
                ));
            }
        }
        check_material(AT, spec)?;
        let triangles = check_triangles(rest, &spec.triangles)?;
        let uvs = check_uvs(spec.uvs.as_deref(), n)?;
        let at = |k: u32| DVec3::from(rest[k as usize]);
        let area: Vec<f64> = triangles
            .iter()
            .map(|t| 0.5 * (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0])).length())
            .collect();
        let mut masses = vec![0.0; n];
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                masses[v as usize] += spec.density * area[t] / 3.0;
            }
        }
        if let Some(k) = masses.iter().position(|&m| m == 0.0) {
            return Err(Error::value(
                format!("{AT}.vertices[{k}]"),
                "is used by no triangle: an unreferenced vertex has no mass; remove it \
                 (vertex k is particle k, so the cloth does not drop it for you)",
            ));
        }
        if let Some((k, m)) = masses
            .iter()
            .enumerate()
            .find(|(_, &m)| (m as f32) == 0.0 || !(1.0 / m as f32).is_finite())
        {
            return Err(Error::value(
                format!("{AT}.density"),
                format!(
                    "vertex {k}'s lumped mass ({m:e} kg) must be representable in float32 \
                     with a finite inverse"
                ),
            ));
        }
        let mut springs = springs_of(rest, &triangles, &area, spec)?;
        let sew_time = match &spec.seams {
            Some(seams) => add_seams(&mut springs, rest, seams)?,
            None => 0.0,
        };
        let place = local_order(n, &springs);
        if let Some(place) = &place {
            springs.sort_along(place);
        }
        let (offsets, incident) = incidence(n, &springs);
        let lanes = IncidenceLanes::new(&offsets, &incident, springs.len());
        let local = place.map(|place| LocalNumbering::new(place, &springs, &offsets, &incident));
        // Every edge has one stretch spring, at its rest length.
        let edges = (0..springs.len()).filter(|&s| springs.kind[s] == EdgeKind::Stretch);
        let (total, count) = edges.fold((0.0, 0), |(t, c), s| (t + springs.rest[s] as f64, c + 1));
        let mean_edge = total / count as f64;
        let membrane = (spec.membrane == super::MembraneKind::Triangle)
            .then(|| Membrane::new(rest, &triangles, &springs, spec.stretch, spec.poisson));
        Ok(MeshCloth {
            membrane,
            mean_edge,
            rest: rest.clone(),
            triangles,
            uvs,
            masses,
            springs,
            offsets,
            incident,
            lanes,
            local,
            sew_time,
        })
    }

    /// The fraction of its starting length a seam spring's rest length has at `time` (s):
    /// `1 - time / sew_time` down to 0, then 0 (sewn). 0 without seams.
    pub fn sewing(&self, time: f64) -> f32 {
        if self.sew_time > 0.0 {
            (1.0 - time / self.sew_time).max(0.0) as f32
        } else {
            0.0
        }
    }

    /// The vertex pairs sewn together: each seam spring's ends, lower index first.
    pub fn seam_pairs(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        let s = &self.springs;
        (0..s.len())
            .filter(|&k| s.kind[k] == EdgeKind::Seam)
            .map(|k| [s.a[k], s.b[k]])
    }

    pub fn len(&self) -> usize {
        self.rest.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// The largest squared angular frequency (rad^2/s^2) of the springs alone, bounded by
    /// Gershgorin's theorem on the mass-scaled stiffness at rest: `2 sum_e k_e / m_v` at the
    /// worst vertex. An upper bound, so a step chosen from it is on the safe side.
    /// With the triangle membrane, each vertex adds its elements' largest row sum of `|K|`
    /// at rest ([`Membrane::row_sums`]), bounded the same way.
    pub fn max_omega2(&self) -> f64 {
        let Some(membrane) = &self.membrane else {
            return self.per_vertex_max(|s| self.springs.k[s] as f64);
        };
        let rest = crate::soa::Vec3s::from_fn(self.len(), |v| DVec3::from(self.rest[v]).as_vec3());
        let rows = membrane.row_sums(&rest);
        (0..self.len())
            .map(|v| {
                let springs = (self.springs_at(v).iter())
                    .map(|&e| self.springs.k[(e >> 1) as usize] as f64)
                    .sum::<f64>();
                (2.0 * springs + rows[v] as f64) / self.masses[v]
            })
            .fold(0.0, f64::max)
    }

    /// The largest damping rate (1/s) of the springs, `2 sum_e c_e / m_v`, bounded the same way.
    pub fn max_damping_rate(&self) -> f64 {
        self.per_vertex_max(|s| self.springs.c[s] as f64)
    }

    /// The springs touching vertex `v`, each as `spring << 1 | end` (`end` 1 at its `b`).
    pub fn springs_at(&self, v: usize) -> &[u32] {
        &self.incident[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// The other end of each live spring touching vertex `v` (edge and bend neighbours).
    pub fn neighbours(&self, v: usize) -> impl Iterator<Item = usize> + '_ {
        let live = |&&e: &&u32| self.springs.active[(e >> 1) as usize];
        self.springs_at(v).iter().filter(live).map(|&e| {
            let s = (e >> 1) as usize;
            let other = if e & 1 == 0 {
                self.springs.b[s]
            } else {
                self.springs.a[s]
            };
            other as usize
        })
    }

    fn per_vertex_max(&self, value: impl Fn(usize) -> f64) -> f64 {
        (0..self.len())
            .map(|v| {
                let around = (self.springs_at(v).iter())
                    .map(|&e| value((e >> 1) as usize))
                    .sum::<f64>();
                2.0 * around / self.masses[v]
            })
            .fold(0.0, f64::max)
    }

    pub fn heap_bytes(&self) -> usize {
        self.rest.capacity() * 24
            + self.triangles.capacity() * 12
            + self.uvs.as_ref().map_or(0, |u| u.capacity() * 8)
            + self.masses.capacity() * 8
            + self.springs.heap_bytes()
            + (self.offsets.capacity() + self.incident.capacity()) * 4
            + self.lanes.heap_bytes()
            + self.local.as_ref().map_or(0, LocalNumbering::heap_bytes)
            + self.membrane.as_ref().map_or(0, Membrane::heap_bytes)
    }
}

/// The smallest altitude of any triangle of a checked mesh (m): the shortest distance from a
/// corner to the line through the opposite edge, `2 A / l` for the triangle's longest edge.
pub(crate) fn min_altitude(vertices: &[[f64; 3]], triangles: &[[i64; 3]]) -> f64 {
    let at = |k: i64| DVec3::from(vertices[k as usize]);
    triangles
        .iter()
        .map(|&[a, b, c]| {
            let (p, q, r) = (at(a), at(b), at(c));
            let twice_area = (q - p).cross(r - p).length();
            let longest = (q - p).length().max((r - q).length()).max((p - r).length());
            twice_area / longest
        })
        .fold(f64::INFINITY, f64::min)
}

/// The triangles as `u32` indices, after every check on them.
fn check_triangles(rest: &[[f64; 3]], triangles: &[[i64; 3]]) -> Result<Vec<[u32; 3]>> {
    let n = rest.len();
    if triangles.is_empty() {
        return Err(Error::value(
            format!("{AT}.triangles"),
            "must hold at least one triangle, got none",
        ));
    }
    let mut out = Vec::with_capacity(triangles.len());
    let mut seen: HashMap<[u32; 3], usize> = HashMap::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        let name = format!("{AT}.triangles[{t}]");
        check_indices(&name, tri, n)?;
        if has_zero_area(rest, tri) {
            return Err(Error::value(
                name,
                format!(
                    "triangle {tri:?} has zero area (repeated or collinear corners): it has no \
                     mass and no normal; remove it"
                ),
            ));
        }
        let tri = tri.map(|k| k as u32);
        let mut key = tri;
        key.sort_unstable();
        if let Some(first) = seen.insert(key, t) {
            return Err(Error::value(
                name,
                format!("triangle {tri:?} repeats triangle {first}: remove one of them"),
            ));
        }
        out.push(tri);
    }
    check_edges(&out)?;
    Ok(out)
}

/// Every edge as `(undirected key, triangle, corner)`, sorted: an edge's uses lie side by side.
fn edge_uses(triangles: &[[u32; 3]]) -> Vec<(u64, u32, u8)> {
    let mut uses = Vec::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            uses.push(((a.min(b) as u64) << 32 | a.max(b) as u64, t as u32, k as u8));
        }
    }
    uses.sort_unstable();
    uses
}

/// Refuses a non-manifold edge and two triangles that walk their shared edge the same way,
/// naming the later triangle.
fn check_edges(triangles: &[[u32; 3]]) -> Result<()> {
    let directed = |t: u32, k: u8| {
        let tri = triangles[t as usize];
        (tri[k as usize], tri[(k as usize + 1) % 3])
    };
    for run in edge_uses(triangles).chunk_by(|x, y| x.0 == y.0) {
        let (a, b) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
        if run.len() > 2 {
            let ts: Vec<u32> = run.iter().map(|u| u.1).collect();
            return Err(Error::value(
                format!("{AT}.triangles[{}]", run[2].1),
                format!(
                    "edge ({a}, {b}) is shared by {} triangles {ts:?}: a non-manifold edge \
                     (more than two triangles) is not supported; split the mesh there",
                    run.len()
                ),
            ));
        }
        if run.len() == 2 && directed(run[0].1, run[0].2) == directed(run[1].1, run[1].2) {
            return Err(Error::value(
                format!("{AT}.triangles[{}]", run[1].1),
                format!(
                    "runs edge ({a}, {b}) the same way as triangle {}: the two are wound \
                     inconsistently (their normals disagree); reverse one",
                    run[0].1
                ),
            ));
        }
    }
    Ok(())
}

/// The material's keys, named under `at`: the density, the moduli, and `poisson` in `[0, 1)`,
/// left at its default unless `membrane = "triangle"` reads it.
fn check_material(at: &str, spec: &MeshSpec) -> Result<()> {
    check_scalar(&format!("{at}.density"), spec.density, Bound::Positive)?;
    check_scalar(&format!("{at}.stretch"), spec.stretch, Bound::NonNegative)?;
    check_scalar(&format!("{at}.bend"), spec.bend, Bound::NonNegative)?;
    check_scalar(&format!("{at}.damping"), spec.damping, Bound::NonNegative)?;
    let name = format!("{at}.poisson");
    if spec.membrane == super::MembraneKind::Springs {
        if spec.poisson != MeshSpec::default().poisson {
            return Err(Error::value(
                name,
                format!(
                    "is the triangle membrane's Poisson ratio; set {at}.membrane = \"triangle\" \
                     or remove it"
                ),
            ));
        }
        return Ok(());
    }
    if !(0.0..1.0).contains(&spec.poisson) {
        return Err(Error::value(
            name,
            format!("must be in [0, 1), got {}", spec.poisson),
        ));
    }
    Ok(())
}

fn check_uvs(uvs: Option<&[[f64; 2]]>, n: usize) -> Result<Option<Vec<[f32; 2]>>> {
    let Some(uvs) = uvs else { return Ok(None) };
    if uvs.len() != n {
        return Err(Error::value(
            format!("{AT}.uvs"),
            format!("must hold one pair per vertex ({n}), got {}", uvs.len()),
        ));
    }
    for (k, uv) in uvs.iter().enumerate() {
        check_vector(&format!("{AT}.uvs[{k}]"), uv, Bound::Any)?;
    }
    Ok(Some(uvs.iter().map(|uv| uv.map(|x| x as f32)).collect()))
}

/// Stretch springs on the edges, then bend springs across the interior edges, each with the
/// stiffness and damping of the area it stands for (see the module doc).
fn springs_of(
    rest: &[[f64; 3]],
    triangles: &[[u32; 3]],
    area: &[f64],
    spec: &MeshSpec,
) -> Result<EdgeSprings> {
    let at = |k: u32| DVec3::from(rest[k as usize]);
    let uses = edge_uses(triangles);
    let runs: Vec<&[(u64, u32, u8)]> = uses.chunk_by(|x, y| x.0 == y.0).collect();
    let mut springs = EdgeSprings::default();
    let ends = |key: u64| ((key >> 32) as u32, key as u32);
    // Under the triangle membrane the elements hold the stretch and shear: every edge keeps a
    // stretch spring for its damping, for strain limiting, cuts and tears, with no stiffness.
    let triangle = spec.membrane == super::MembraneKind::Triangle;
    let add = |springs: &mut EdgeSprings, (a, b): (u32, u32), share: f64, kind| {
        let (modulus, damping) = match kind {
            EdgeKind::Stretch if triangle => (0.0, spec.damping),
            EdgeKind::Stretch => (spec.stretch, spec.damping),
            EdgeKind::Bend => (spec.bend, spec.damping),
            EdgeKind::Seam => unreachable!("seams are added apart"),
        };
        if modulus == 0.0 && !(triangle && kind == EdgeKind::Stretch) {
            return;
        }
        let rest = (at(b) - at(a)).length();
        let scale = share / (rest * rest);
        springs.push((a, b), rest, modulus * scale, damping * scale, kind);
    };
    for run in &runs {
        let share = run.iter().map(|u| area[u.1 as usize]).sum::<f64>() / 3.0;
        add(&mut springs, ends(run[0].0), share, EdgeKind::Stretch);
    }
    let opposite = |t: u32, k: u8| triangles[t as usize][(k as usize + 2) % 3];
    let mut bends: Vec<((u32, u32), f64)> = runs
        .iter()
        .filter(|run| run.len() == 2)
        .map(|run| {
            let (c, d) = (opposite(run[0].1, run[0].2), opposite(run[1].1, run[1].2));
            let share = (area[run[0].1 as usize] + area[run[1].1 as usize]) / 3.0;
            ((c.min(d), c.max(d)), share)
        })
        .collect();
    bends.sort_by_key(|&(pair, _)| pair);
    for (pair, share) in bends {
        // Two triangles folded flat onto each other across the edge would put the opposite
        // vertices together: a bend spring of no length has no direction.
        if (at(pair.1) - at(pair.0)).length() <= DEGENERATE {
            return Err(Error::value(
                format!("{AT}.vertices[{}]", pair.1),
                format!(
                    "lies on vertex {} across a shared edge: the two triangles are folded \
                     flat onto each other",
                    pair.0
                ),
            ));
        }
        add(&mut springs, pair, share, EdgeKind::Bend);
    }
    Ok(springs)
}

/// Appends the seam springs of `seams` (checked: indices in range, two different vertices,
/// no pair twice) and returns the sewing time.
fn add_seams(springs: &mut EdgeSprings, rest: &[[f64; 3]], seams: &SeamsSpec) -> Result<f64> {
    let at = format!("{AT}.seams");
    check_scalar(&format!("{at}.sew_time"), seams.sew_time, Bound::Positive)?;
    check_scalar(&format!("{at}.stiffness"), seams.stiffness, Bound::Positive)?;
    check_scalar(&format!("{at}.damping"), seams.damping, Bound::NonNegative)?;
    let mut seen: HashMap<(u32, u32), usize> = HashMap::with_capacity(seams.pairs.len());
    for (s, pair) in seams.pairs.iter().enumerate() {
        let name = format!("{at}.pairs[{s}]");
        for &v in pair {
            if !(0..rest.len() as i64).contains(&v) {
                return Err(Error::IndexOutOfRange {
                    name,
                    index: v,
                    len: rest.len(),
                });
            }
        }
        let (a, b) = (pair[0] as u32, pair[1] as u32);
        if a == b {
            return Err(Error::value(name, format!("sews vertex {a} to itself")));
        }
        if let Some(first) = seen.insert((a.min(b), a.max(b)), s) {
            return Err(Error::value(name, format!("repeats pairs[{first}]")));
        }
        let d = (DVec3::from(rest[b as usize]) - DVec3::from(rest[a as usize])).length();
        springs.push((a, b), d, seams.stiffness, seams.damping, EdgeKind::Seam);
    }
    Ok(seams.sew_time)
}

impl ClothSpec {
    /// Compiles `garment` into `mesh` (and clears it): its vertices, triangles, UVs, material
    /// and seams. A cloth with both is refused.
    pub(super) fn sew_garment(&mut self) -> Result<()> {
        let Some(garment) = self.garment.take() else {
            return Ok(());
        };
        if self.mesh.is_some() {
            return Err(Error::value(
                "cloth.garment",
                "a cloth is a garment or a mesh (cloth.mesh), not both",
            ));
        }
        let material = MeshSpec {
            density: garment.density,
            stretch: garment.stretch,
            bend: garment.bend,
            damping: garment.damping,
            membrane: garment.membrane,
            poisson: garment.poisson,
            ..MeshSpec::default()
        };
        check_material("cloth.garment", &material)?;
        let sewn = garment.compile()?;
        self.mesh = Some(MeshSpec {
            vertices: sewn.vertices,
            triangles: sewn.triangles,
            uvs: Some(sewn.uvs),
            seams: (!sewn.seams.is_empty()).then_some(SeamsSpec {
                pairs: sewn.seams,
                sew_time: garment.sew_time,
                stiffness: garment.seam_stiffness,
                damping: garment.seam_damping,
            }),
            ..material
        });
        Ok(())
    }
}

/// Each vertex's place in a local order of the mesh's springs (seams apart: they join pieces
/// that the order takes one after another; [`crate::linear::amg::local_order`]), or None where
/// that is the vertex numbering: a mesh numbered row by row is local already, one read from a
/// file in a scattered order gets a breadth-first order.
fn local_order(n: usize, springs: &EdgeSprings) -> Option<Vec<u32>> {
    let mesh = (0..springs.len()).filter(|&e| springs.kind[e] != EdgeKind::Seam);
    let mut offsets = vec![0usize; n + 1];
    for e in mesh.clone() {
        offsets[springs.a[e] as usize + 1] += 1;
        offsets[springs.b[e] as usize + 1] += 1;
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    let mut next = offsets.clone();
    let mut neighbours = vec![0u32; offsets[n]];
    for e in mesh {
        let (a, b) = (springs.a[e], springs.b[e]);
        for (v, other) in [(a, b), (b, a)] {
            neighbours[next[v as usize]] = other;
            next[v as usize] += 1;
        }
    }
    let order = crate::linear::amg::local_order(&vec![true; n], &offsets, &neighbours);
    if order.iter().enumerate().all(|(k, &v)| k == v as usize) {
        return None;
    }
    let mut place = vec![0u32; n];
    for (k, &v) in order.iter().enumerate() {
        place[v as usize] = k as u32;
    }
    Some(place)
}

/// A local numbering of a mesh cloth's vertices, in which the force pass works where the
/// user's numbering is scattered: it gathers the positions and velocities into it, runs its
/// two passes there ([`crate::mesh_cloth::forces`]) and scatters the forces back. Each
/// vertex's springs are the same, summed in the same order, so the forces are bitwise those of
/// the passes in the user's numbering; only the gathers come from a few cache lines instead
/// of the whole state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocalNumbering {
    /// `vertices[k]` is the vertex numbered `k` here, and `place[v]` vertex `v`'s number.
    pub vertices: Vec<u32>,
    pub place: Vec<u32>,
    /// Each spring's ends in this numbering (the lower vertex index first, as in the list).
    pub a: Vec<u32>,
    pub b: Vec<u32>,
    /// The springs touching each vertex of this numbering, laid out as [`MeshCloth::lanes`].
    pub lanes: IncidenceLanes,
}

impl LocalNumbering {
    fn new(place: Vec<u32>, springs: &EdgeSprings, offsets: &[u32], incident: &[u32]) -> Self {
        let mut vertices = vec![0u32; place.len()];
        for (v, &k) in place.iter().enumerate() {
            vertices[k as usize] = v as u32;
        }
        let mut local_offsets = vec![0u32];
        let mut local_incident = Vec::with_capacity(incident.len());
        for &v in &vertices {
            let v = v as usize;
            local_incident
                .extend_from_slice(&incident[offsets[v] as usize..offsets[v + 1] as usize]);
            local_offsets.push(local_incident.len() as u32);
        }
        let lanes = IncidenceLanes::new(&local_offsets, &local_incident, springs.len());
        LocalNumbering {
            a: springs.a.iter().map(|&v| place[v as usize]).collect(),
            b: springs.b.iter().map(|&v| place[v as usize]).collect(),
            vertices,
            place,
            lanes,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.vertices.capacity() + self.place.capacity()) * 4
            + (self.a.capacity() + self.b.capacity()) * 4
            + self.lanes.heap_bytes()
    }
}

/// For each vertex, the springs that touch it, in increasing order (CSR).
fn incidence(n: usize, springs: &EdgeSprings) -> (Vec<u32>, Vec<u32>) {
    let mut count = vec![0u32; n + 1];
    for s in 0..springs.len() {
        count[springs.a[s] as usize + 1] += 1;
        count[springs.b[s] as usize + 1] += 1;
    }
    for v in 0..n {
        count[v + 1] += count[v];
    }
    let offsets = count.clone();
    let mut next = count;
    let mut incident = vec![0u32; 2 * springs.len()];
    for s in 0..springs.len() {
        for (end, v) in [(0, springs.a[s]), (1, springs.b[s])] {
            incident[next[v as usize] as usize] = (s as u32) << 1 | end;
            next[v as usize] += 1;
        }
    }
    (offsets, incident)
}
