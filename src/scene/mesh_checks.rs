//! The checks that refuse a bad cloth mesh, each error naming the parameter and the offending
//! vertex, triangle or edge: triangles (indices, zero area, repeats), edges (non-manifold,
//! inconsistent winding), the material's keys and the UVs.

use std::collections::HashMap;

use glam::DVec3;

use super::mesh::{check_indices, has_zero_area};
use super::MeshSpec;
use crate::error::{check_scalar, check_vector, Bound, Error, Result};

/// Where a scene keeps the mesh, for error names.
pub(super) const AT: &str = "cloth.mesh";

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
pub(super) fn check_triangles(rest: &[[f64; 3]], triangles: &[[i64; 3]]) -> Result<Vec<[u32; 3]>> {
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
pub(super) fn edge_uses(triangles: &[[u32; 3]]) -> Vec<(u64, u32, u8)> {
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
pub(super) fn check_material(at: &str, spec: &MeshSpec) -> Result<()> {
    check_scalar(&format!("{at}.density"), spec.density, Bound::Positive)?;
    check_scalar(&format!("{at}.stretch"), spec.stretch, Bound::NonNegative)?;
    check_scalar(&format!("{at}.bend"), spec.bend, Bound::NonNegative)?;
    check_scalar(&format!("{at}.damping"), spec.damping, Bound::NonNegative)?;
    let modulus = format!("{at}.bend_modulus");
    check_scalar(&modulus, spec.bend_modulus, Bound::NonNegative)?;
    if spec.bending == super::BendingKind::Springs
        && spec.bend_modulus != MeshSpec::default().bend_modulus
    {
        return Err(Error::value(
            modulus,
            format!(
                "is the isometric bending's modulus; set {at}.bending = \"isometric\" or \
                 remove it"
            ),
        ));
    }
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

pub(super) fn check_uvs(uvs: Option<&[[f64; 2]]>, n: usize) -> Result<Option<Vec<[f32; 2]>>> {
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
