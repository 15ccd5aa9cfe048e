//! A mesh cloth from its [`MeshSpec`]: the checks that refuse a bad mesh (each error names the
//! parameter and the offending vertex or triangle; [`super::mesh_checks`]), then the lumped
//! masses and the springs. The model and its equations: [`crate::mesh_cloth`].

use std::collections::HashMap;

use glam::DVec3;

use super::bending::IsometricBending;
use super::edge_springs::{EdgeKind, EdgeSprings};
use super::local_numbering::{incidence, local_order, LocalNumbering};
use super::mesh_checks::{check_material, check_triangles, check_uvs, edge_uses, AT};
use super::Membrane;
use super::{ClothSpec, FlatPanels, IncidenceLanes, MeshSpec, SeamsSpec, SpringSlots};
use crate::error::{check_scalar, check_vector, Bound, Error, Result};

/// Two vertices closer than this (m) are one point.
const DEGENERATE: f64 = f32::EPSILON as f64;

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
    /// What the force pass reads per slot of the lanes it runs on (`local`'s where there is
    /// one, else `lanes`), kept in step with `springs` by [`MeshCloth::refresh_cut_springs`].
    pub slots: SpringSlots,
    /// The mean length of the mesh's edges at rest (m): its spacing, where the grid has one.
    pub mean_edge: f64,
    /// Seconds over which the seams close (0 without seams).
    pub sew_time: f64,
    /// The triangle elements of `membrane = "triangle"`, which then hold the stretch and
    /// shear (the stretch springs keep only their damping); None with `"springs"`.
    pub membrane: Option<Membrane>,
    /// The isometric bending elements of `bending = "isometric"` (the bend springs keep only
    /// their damping); None with `"springs"`.
    pub bending: Option<IsometricBending>,
    /// A garment's triangles on their flat panels, one per triangle (None for another mesh).
    pub panels: Option<FlatPanels>,
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
        let bending = match spec.bending {
            super::BendingKind::Springs => None,
            super::BendingKind::Isometric => Some(IsometricBending::new(
                AT,
                rest,
                &interior_edges(&triangles),
                &springs,
                spec.bend_modulus,
            )?),
        };
        if let Some(p) = &spec.panels {
            let t = triangles.len();
            if p.panel.len() != t || p.corners.len() != t {
                return Err(Error::value(
                    format!("{AT}.panels"),
                    format!(
                        "must hold one panel and one set of corners per triangle ({t}), got {} \
                         and {}",
                        p.panel.len(),
                        p.corners.len()
                    ),
                ));
            }
            if let Some(k) = p
                .corners
                .iter()
                .position(|c| !c.as_flattened().iter().all(|x| x.is_finite()))
            {
                return Err(Error::value(
                    format!("{AT}.panels.corners[{k}]"),
                    "must be finite",
                ));
            }
        }
        let panels = spec.panels.clone();
        let linear = bending.as_ref().map(|b| &b.linear[..]);
        let slots = slots_of(&lanes, local.as_ref(), &springs, linear, n);
        Ok(MeshCloth {
            panels,
            membrane,
            bending,
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
            slots,
            sew_time,
        })
    }

    /// Sets the numbering the force pass works in (None: the user's), with its
    /// [`MeshCloth::slots`].
    pub fn set_local(&mut self, local: Option<LocalNumbering>) {
        let linear = self.bending.as_ref().map(|b| &b.linear[..]);
        let n = self.len();
        self.slots = slots_of(&self.lanes, local.as_ref(), &self.springs, linear, n);
        self.local = local;
    }

    /// Recomputes what follows the parameters of the `changed` springs after a cut or a tear:
    /// the isometric bending's per-spring terms from the springs that hold (an element goes
    /// with any of its six springs, which changes its other springs' terms, so every slot is
    /// copied again), else only the changed springs' slots ([`SpringSlots::refresh_springs`]).
    pub fn refresh_cut_springs(&mut self, changed: &[u32]) {
        match &mut self.bending {
            Some(bending) => {
                bending.refresh(&self.springs.active);
                self.slots.refresh(&self.springs, Some(&bending.linear));
            }
            None => self.slots.refresh_springs(&self.springs, changed),
        }
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
            return self.per_vertex_max(|s| self.stiffness(s));
        };
        let rest = crate::soa::Vec3s::from_fn(self.len(), |v| DVec3::from(self.rest[v]).as_vec3());
        let rows = membrane.row_sums(&rest);
        (0..self.len())
            .map(|v| {
                let springs = (self.springs_at(v).iter())
                    .map(|&e| self.stiffness((e >> 1) as usize))
                    .sum::<f64>();
                (2.0 * springs + rows[v] as f64) / self.masses[v]
            })
            .fold(0.0, f64::max)
    }

    /// Spring `s`'s stiffness for the stability bound: its `k`, plus `|w|` of the isometric
    /// bending's linear term on its pair (a row of the bending's Hessian sums to zero, so its
    /// diagonal is at most the sum of `|w|` off it, and the factor 2 of the bound covers it).
    fn stiffness(&self, s: usize) -> f64 {
        let linear = self.bending.as_ref().map_or(0.0, |b| b.linear[s].abs());
        self.springs.k[s] as f64 + linear as f64
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
            + self.slots.heap_bytes()
            + self.local.as_ref().map_or(0, LocalNumbering::heap_bytes)
            + self.membrane.as_ref().map_or(0, Membrane::heap_bytes)
            + self
                .bending
                .as_ref()
                .map_or(0, IsometricBending::heap_bytes)
            + (self.panels.as_ref())
                .map_or(0, |p| p.panel.capacity() * 4 + p.corners.capacity() * 48)
    }
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
    // Under isometric bending the elements hold the bending: every interior edge keeps its
    // bend spring, and every edge its stretch spring, for the damping, the linear term of
    // their pair and the elements' liveness, whatever the moduli.
    let isometric = spec.bending == super::BendingKind::Isometric;
    let add = |springs: &mut EdgeSprings, (a, b): (u32, u32), share: f64, kind| {
        let (modulus, damping) = match kind {
            EdgeKind::Stretch if triangle => (0.0, spec.damping),
            EdgeKind::Stretch => (spec.stretch, spec.damping),
            EdgeKind::Bend if isometric => (0.0, spec.damping),
            EdgeKind::Bend => (spec.bend, spec.damping),
            EdgeKind::Seam => unreachable!("seams are added apart"),
        };
        let kept = (triangle && kind == EdgeKind::Stretch) || isometric;
        if modulus == 0.0 && !kept {
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

/// Each interior edge's two vertices, then the vertex opposite it in each of its triangles.
fn interior_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 4]> {
    let uses = edge_uses(triangles);
    let opposite = |t: u32, k: u8| triangles[t as usize][(k as usize + 2) % 3];
    uses.chunk_by(|x, y| x.0 == y.0)
        .filter(|run| run.len() == 2)
        .map(|run| {
            let (a, b) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
            [
                a,
                b,
                opposite(run[0].1, run[0].2),
                opposite(run[1].1, run[1].2),
            ]
        })
        .collect()
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
            panels: Some(sewn.panels),
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

/// The force pass's slots ([`SpringSlots`]) of a cloth's springs over `n` vertices, in `local`
/// where it has one, else in the user's numbering (`lanes`).
fn slots_of(
    lanes: &IncidenceLanes,
    local: Option<&LocalNumbering>,
    springs: &EdgeSprings,
    linear: Option<&[f32]>,
    n: usize,
) -> SpringSlots {
    match local {
        Some(l) => SpringSlots::new((&l.lanes, true), (&l.a, &l.b), springs, linear, n),
        None => SpringSlots::new((lanes, false), (&springs.a, &springs.b), springs, linear, n),
    }
}
