//! A mesh cloth's springs, one struct of arrays: each spring's ends, rest length, stiffness,
//! damping and what it stands for (an edge, a bend across an edge, a seam).

/// What a spring of a mesh cloth stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EdgeKind {
    /// On an edge of the mesh.
    Stretch,
    /// Across an interior edge, between the two opposite vertices.
    Bend,
    /// A seam: two vertices sewn together. Its listed rest length is the pair's starting
    /// distance, scaled down to zero over the cloth's `sew_time` ([`super::MeshCloth::sewing`]).
    Seam,
}

/// The springs of a mesh cloth as an explicit list, sorted by kind, then by their ends in the
/// mesh's local order (the vertex numbering, or [`super::LocalNumbering`]'s where that is
/// scattered).
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

    pub(super) fn push(&mut self, (a, b): (u32, u32), rest: f64, k: f64, c: f64, kind: EdgeKind) {
        self.a.push(a.min(b));
        self.b.push(a.max(b));
        self.rest.push(rest as f32);
        self.k.push(k as f32);
        self.c.push(c as f32);
        self.kind.push(kind);
        self.active.push(true);
    }

    /// Spring `e`'s rest length when the seams are at `sewing` of their starting length
    /// ([`super::MeshCloth::sewing`]), or None when it is a seam that is slack at length `l`: a
    /// seam is a thread, it pulls its ends together and never pushes them apart. The force pass
    /// applies the same rule, written for the vector unit.
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
    pub(super) fn sort_along(&mut self, rank: &[u32]) {
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
