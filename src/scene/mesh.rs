//! A mesh collider's `vertices` and `triangles`: their checks (finite vertices, indices in
//! range, no zero-area triangle, a closed mesh wound consistently and outwards) and whether the
//! mesh is closed, which decides how the collider tells inside from outside.

use std::collections::HashMap;

use glam::DVec3;

use crate::error::{check_vector, Bound, Error, Result};

/// A triangle whose doubled area `|(b - a) x (c - a)|` is at most this times its longest edge
/// squared has zero area in float32 (where the collider works): refused as degenerate.
const DEGENERATE: f64 = f32::EPSILON as f64;

/// The vertex each vertex stands for once exact duplicates are merged (the first with its
/// position), so that a mesh written with one vertex per corner (as OBJ files with normals or
/// texture coordinates often are) still has shared edges.
pub fn merged_indices(vertices: &[[f64; 3]]) -> Vec<u32> {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(vertices.len());
    vertices
        .iter()
        .enumerate()
        .map(|(k, v)| {
            // As float32, the precision the collider keeps: two vertices that round to the same
            // point are the same vertex there.
            let key = v.map(|x| ((x as f32) + 0.0).to_bits() as u64);
            *first.entry(key).or_insert(k as u32)
        })
        .collect()
}

/// Whether the mesh is closed: every edge (between merged vertices) is shared by exactly two
/// triangles. `Err` names `at.triangles` when a closed mesh is wound inconsistently (an edge
/// walked the same way by both its triangles) or inside out (negative enclosed volume).
pub fn is_closed(at: &str, vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> Result<bool> {
    let merged = merged_indices(vertices);
    // Every corner's edge as (undirected key, triangle, corner), sorted: an edge's uses lie
    // side by side. A sort, rather than a hash map, since a million-triangle mesh has three
    // million of them.
    let mut uses: Vec<(u64, u32, u8)> = Vec::with_capacity(3 * triangles.len());
    let directed = |t: usize, k: usize| {
        let tri = triangles[t];
        (merged[tri[k] as usize], merged[tri[(k + 1) % 3] as usize])
    };
    for t in 0..triangles.len() {
        for k in 0..3 {
            let (a, b) = directed(t, k);
            uses.push(((a.min(b) as u64) << 32 | a.max(b) as u64, t as u32, k as u8));
        }
    }
    uses.sort_unstable();
    let runs = || uses.chunk_by(|x, y| x.0 == y.0);
    if runs().any(|run| run.len() != 2) {
        return Ok(false);
    }
    // Both triangles of an edge walking it the same way. The one reported is the first a walk
    // in triangle and corner order meets, whatever the sort did.
    let same_way = runs()
        .filter(|run| {
            directed(run[0].1 as usize, run[0].2 as usize)
                == directed(run[1].1 as usize, run[1].2 as usize)
        })
        .map(|run| (run[1].1, run[1].2, run[0].1))
        .min();
    if let Some((t, k, other)) = same_way {
        let edge = directed(t as usize, k as usize);
        return Err(Error::value(
            format!("{at}.triangles"),
            format!(
                "the mesh is closed but wound inconsistently: triangles {other} and {t} both \
                 run their shared edge the same way (merged vertices {} to {}); give every \
                 triangle the same order, counter-clockwise from outside",
                edge.0, edge.1
            ),
        ));
    }
    // Six times the enclosed volume, by the divergence theorem: negative when inside out.
    let volume: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| DVec3::from(vertices[k as usize]));
            a.dot(b.cross(c))
        })
        .sum();
    if volume < 0.0 {
        return Err(Error::value(
            format!("{at}.triangles"),
            format!(
                "the closed mesh is wound inside out (enclosed volume {:.3e} m^3 < 0): its \
                 triangles must run counter-clockwise seen from outside; reverse each one's order",
                volume / 6.0
            ),
        ));
    }
    Ok(true)
}

/// Refuses a triangle `name` with an index outside `0..n`, naming the index.
pub(crate) fn check_indices(name: &str, tri: &[i64; 3], n: usize) -> Result<()> {
    match tri.iter().find(|&&k| !(0..n as i64).contains(&k)) {
        Some(&k) => Err(Error::value(
            name,
            format!(
                "index {k} is out of range for {n} vertices (0 to {})",
                n - 1
            ),
        )),
        None => Ok(()),
    }
}

/// Whether the triangle (indices checked) has zero area in float32, where the solver works:
/// repeated or collinear corners.
pub(crate) fn has_zero_area(vertices: &[[f64; 3]], tri: &[i64; 3]) -> bool {
    let [a, b, c] = tri.map(|k| DVec3::from(vertices[k as usize].map(|x| x as f32 as f64)));
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    (b - a).cross(c - a).length() <= DEGENERATE * longest
}

/// Checks `vertices` and `triangles` of the mesh collider `at` (`colliders[c]`) and returns the
/// triangles as `u32` indices. `within` bounds every coordinate (see `MAX_COLLIDER_VALUE`).
pub fn check_mesh(
    at: &str,
    vertices: &[[f64; 3]],
    triangles: &[[i64; 3]],
    within: impl Fn(&str, &[f64]) -> Result<()>,
) -> Result<Vec<[u32; 3]>> {
    if vertices.len() < 3 {
        return Err(Error::value(
            format!("{at}.vertices"),
            format!("must hold at least 3 vertices, got {}", vertices.len()),
        ));
    }
    if vertices.len() > u32::MAX as usize {
        return Err(Error::value(
            format!("{at}.vertices"),
            format!(
                "must hold at most {} vertices, got {}",
                u32::MAX,
                vertices.len()
            ),
        ));
    }
    for (k, v) in vertices.iter().enumerate() {
        let name = format!("{at}.vertices[{k}]");
        check_vector(&name, v, Bound::Any)?;
        within(&name, v)?;
    }
    if triangles.is_empty() {
        return Err(Error::value(
            format!("{at}.triangles"),
            "must hold at least one triangle, got none (an empty mesh)",
        ));
    }
    let n = vertices.len();
    let mut out = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        check_indices(&format!("{at}.triangles[{t}]"), tri, n)?;
        if has_zero_area(vertices, tri) {
            return Err(Error::value(
                format!("{at}.triangles[{t}]"),
                format!(
                    "triangle {tri:?} has zero area (repeated or collinear corners): a \
                     degenerate triangle has no normal to push along; remove it"
                ),
            ));
        }
        out.push(tri.map(|k| k as u32));
    }
    Ok(out)
}
