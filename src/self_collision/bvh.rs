//! The broad phase: a bounding-volume tree over the mesh's triangles (or edges), its shape
//! built once for a topology and its boxes refitted every search. A cloth's triangles that are
//! neighbours in the tree are a patch of the cloth, and the springs keep a patch about its rest
//! size however the cloth folds or winds, so a tree built once keeps tight boxes: a query only
//! opens the nodes near it, where a spatial hash sized to the mean box scanned every box of
//! every cell it met (in a wound cloth, many layers per cell).
//!
//! The tree's shape only changes how fast an answer comes, never the answer: every item whose
//! box overlaps the query, which the caller sorts. So a tree built from other positions (a
//! state restored into a new simulation) finds the same pairs.

use glam::{BVec4A, Vec3, Vec3A, Vec4};
use rayon::prelude::*;

/// An axis-aligned box, in m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// Closed boxes: touching counts as overlapping (the test must never miss a pair).
    #[cfg(test)]
    pub fn overlaps(&self, other: &Aabb) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }

    fn centre(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

/// Items in a leaf at most: the four lanes of a vector, so a box is tested against a whole leaf
/// at once (`Quad`).
const LEAF: usize = 4;

/// A box as the tree keeps it: SIMD lanes, so an overlap test is two vector compares.
#[derive(Clone, Copy, Debug)]
struct Lanes {
    min: Vec3A,
    max: Vec3A,
}

impl Lanes {
    const EMPTY: Lanes = Lanes {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    #[inline]
    fn of(b: &Aabb) -> Lanes {
        Lanes {
            min: b.min.into(),
            max: b.max.into(),
        }
    }

    #[inline]
    fn overlaps(&self, other: &Lanes) -> bool {
        (self.min.cmple(other.max) & other.min.cmple(self.max)).all()
    }

    #[inline]
    fn union(&self, other: &Lanes) -> Lanes {
        Lanes {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }
}

/// Levels of the wide walk done on one thread before its front is shared out: a wide node pair
/// opens into up to 16 child pairs, so three levels give enough node pairs to keep every
/// thread busy.
const FRONT_DEPTH: usize = 3;

/// A child of a wide node: a wide node's index, or (`LEAF_BIT` set) a leaf's index among the
/// binary nodes.
const LEAF_BIT: u32 = 1 << 31;

/// A pair of children in the wide walk: `a` of the first tree and `b` of the second, or
/// (`same`) `a` against itself. Their boxes overlap (or `same`).
#[derive(Clone, Copy, Debug)]
struct Walk {
    a: u32,
    b: u32,
    same: bool,
}

impl Walk {
    /// Child `a` of the first tree against child `b` of the second.
    fn across(a: u32, b: u32) -> Walk {
        Walk { a, b, same: false }
    }
}

/// What a walk of [`Bvh::overlapping_pairs`] keeps from one call to the next: its front, its
/// stack, and each run's output and stack, so that a walk finding no more than an earlier one
/// allocates nothing.
pub struct WalkScratch<T> {
    front: Vec<Walk>,
    stack: Stack,
    runs: Vec<(Vec<T>, Stack)>,
}

/// The node pairs a walk has still to open, each with its depth below the walk's root.
type Stack = Vec<(Walk, usize)>;

impl<T> Default for WalkScratch<T> {
    fn default() -> Self {
        WalkScratch {
            front: Vec::new(),
            stack: Vec::new(),
            runs: Vec::new(),
        }
    }
}

impl<T> WalkScratch<T> {
    pub fn heap_bytes(&self) -> usize {
        let walk = size_of::<(Walk, usize)>();
        let runs = self.runs.iter();
        self.front.capacity() * size_of::<Walk>()
            + self.stack.capacity() * walk
            + runs
                .map(|(f, s)| f.capacity() * size_of::<T>() + s.capacity() * walk)
                .sum::<usize>()
    }
}

/// A node of the wide tree: the binary tree with every other level collapsed, so its up to
/// four children are the binary node's children, or their children where those are inner.
/// Their boxes lane by lane, so one box is tested against all four in one compare.
#[derive(Clone, Copy, Debug)]
struct Wide {
    boxes: Quad,
    /// Each child: a wide node, or a leaf (`LEAF_BIT`).
    child: [u32; 4],
    /// Each child's binary node, whose box it has.
    binary: [u32; 4],
    /// How many children (2 to 4).
    count: u32,
}

/// A node: its box and either its two children (the first is the next node, `right` the
/// second) or its items, `order[first..first + count]`.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Lanes,
    /// Leaf: the first of its items in `order`; inner node: its second child.
    index: u32,
    /// Leaf: how many items (at least one); inner node: 0.
    count: u32,
    /// Leaf: its boxes side by side in `quads`.
    quad: u32,
}

/// A leaf's boxes lane by lane (one lane an item, an empty box in lanes without one), so one
/// box is tested against the whole leaf in six vector compares.
#[derive(Clone, Copy, Debug)]
struct Quad {
    min: [Vec4; 3],
    max: [Vec4; 3],
}

impl Quad {
    const EMPTY: Quad = Quad {
        min: [Vec4::INFINITY; 3],
        max: [Vec4::NEG_INFINITY; 3],
    };

    /// Bit `i` set when the leaf's item `i` overlaps `b`.
    #[inline]
    fn overlapping(&self, b: &Lanes) -> u32 {
        let mut hit = BVec4A::splat(true);
        for axis in 0..3 {
            hit &= self.min[axis].cmple(Vec4::splat(b.max[axis]))
                & self.max[axis].cmpge(Vec4::splat(b.min[axis]));
        }
        hit.bitmask()
    }
}

impl Wide {
    /// The children whose boxes overlap `b`, in lane order.
    #[inline]
    fn overlapping(&self, b: &Lanes) -> impl Iterator<Item = u32> + '_ {
        let mut hits = self.boxes.overlapping(b);
        std::iter::from_fn(move || {
            (hits != 0).then(|| {
                let j = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                self.child[j]
            })
        })
    }
}

/// The tree. Nodes are in depth-first order, each parent before its children, so a refit
/// walks them backwards.
#[derive(Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// The items, leaf by leaf.
    order: Vec<u32>,
    /// Their boxes at the last refit, in the same order: a leaf's are side by side in memory.
    leaf_boxes: Vec<Lanes>,
    /// How many items the tree was built for.
    items: usize,
    /// Each leaf's boxes, lane by lane, in the leaves' order.
    quads: Vec<Quad>,
    leaves: u32,
    /// The same tree four children a node, walked by [`Bvh::overlapping_pairs`].
    wide: Vec<Wide>,
    /// The wide tree's root: a wide node, or the single leaf (`LEAF_BIT`).
    wide_root: u32,
}

impl Bvh {
    /// Whether the tree is built for `items` items.
    pub fn is_built_for(&self, items: usize) -> bool {
        self.items == items && (items == 0 || !self.nodes.is_empty())
    }

    /// Shapes the tree for `boxes` (all finite): median splits of their centres along the
    /// longest side of the centres' box, down to leaves of `LEAF` items. Deterministic (ties are
    /// broken by item), and its boxes are those of `boxes`.
    pub fn build(&mut self, boxes: &[Aabb]) {
        self.nodes.clear();
        self.wide.clear();
        self.leaves = 0;
        self.items = boxes.len();
        self.order = (0..boxes.len() as u32).collect();
        if boxes.is_empty() {
            return;
        }
        let centres: Vec<Vec3> = boxes.iter().map(Aabb::centre).collect();
        let mut order = std::mem::take(&mut self.order);
        self.split(&centres, &mut order, 0);
        self.order = order;
        self.wide_root = self.widen(0);
        self.refit(boxes);
    }

    /// Appends the wide node over binary node `k` and those below it; returns its child
    /// reference (a leaf stays a leaf).
    fn widen(&mut self, k: u32) -> u32 {
        let node = self.nodes[k as usize];
        if node.count > 0 {
            return k | LEAF_BIT;
        }
        let at = self.wide.len();
        self.wide.push(Wide {
            boxes: Quad::EMPTY,
            child: [0; 4],
            binary: [0; 4],
            count: 0,
        });
        let mut binary = Vec::with_capacity(4);
        for c in [k + 1, node.index] {
            let n = self.nodes[c as usize];
            if n.count > 0 {
                binary.push(c);
            } else {
                binary.extend([c + 1, n.index]);
            }
        }
        for (lane, &g) in binary.iter().enumerate() {
            let child = self.widen(g);
            let w = &mut self.wide[at];
            (w.child[lane], w.binary[lane]) = (child, g);
            w.count += 1;
        }
        at as u32
    }

    /// Appends the subtree over `items` (which start at `offset` in `order`).
    fn split(&mut self, centres: &[Vec3], items: &mut [u32], offset: usize) {
        let at = self.nodes.len();
        self.nodes.push(Node {
            bounds: Lanes::EMPTY,
            index: offset as u32,
            count: items.len() as u32,
            quad: self.leaves,
        });
        if items.len() <= LEAF {
            self.leaves += 1;
            return;
        }
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &i in items.iter() {
            (lo, hi) = (lo.min(centres[i as usize]), hi.max(centres[i as usize]));
        }
        let side = hi - lo;
        let axis = if side.x >= side.y && side.x >= side.z {
            0
        } else if side.y >= side.z {
            1
        } else {
            2
        };
        let half = items.len() / 2;
        items.select_nth_unstable_by(half, |&a, &b| {
            let (p, q) = (centres[a as usize][axis], centres[b as usize][axis]);
            p.total_cmp(&q).then(a.cmp(&b))
        });
        let (left, right) = items.split_at_mut(half);
        self.split(centres, left, offset);
        let second = self.nodes.len() as u32;
        self.split(centres, right, offset + half);
        self.nodes[at].index = second;
        self.nodes[at].count = 0;
    }

    /// Sets every node's box from `boxes`, the items' boxes now (the tree's shape is kept).
    pub fn refit(&mut self, boxes: &[Aabb]) {
        debug_assert_eq!(boxes.len(), self.items);
        self.leaf_boxes.clear();
        self.leaf_boxes
            .extend(self.order.iter().map(|&i| Lanes::of(&boxes[i as usize])));
        self.quads.resize(self.leaves as usize, Quad::EMPTY);
        for k in (0..self.nodes.len()).rev() {
            let node = self.nodes[k];
            self.nodes[k].bounds = if node.count > 0 {
                let range = node.index as usize..(node.index + node.count) as usize;
                let mut quad = Quad::EMPTY;
                for (lane, b) in self.leaf_boxes[range.clone()].iter().enumerate() {
                    for axis in 0..3 {
                        quad.min[axis][lane] = b.min[axis];
                        quad.max[axis][lane] = b.max[axis];
                    }
                }
                self.quads[node.quad as usize] = quad;
                self.leaf_boxes[range]
                    .iter()
                    .fold(Lanes::EMPTY, |b, l| b.union(l))
            } else {
                self.nodes[k + 1]
                    .bounds
                    .union(&self.nodes[node.index as usize].bounds)
            };
        }
        for w in self.wide.iter_mut() {
            for lane in 0..w.count as usize {
                let b = self.nodes[w.binary[lane] as usize].bounds;
                for axis in 0..3 {
                    w.boxes.min[axis][lane] = b.min[axis];
                    w.boxes.max[axis][lane] = b.max[axis];
                }
            }
        }
    }

    /// Every pair of items whose boxes at the last refit overlap, one item of `self` and one of
    /// `other`, or, with `other` None, two distinct items of `self` (each pair once, in either
    /// order). `emit` is called with each (self's item, the other's) and the output of its
    /// task, and says whether it looked at the pair; the outputs come back in an order fixed by
    /// the trees, whatever the thread count. Returns how many boxes it tested and how many
    /// pairs `emit` looked at.
    ///
    /// Both trees are walked at once (a bounding-volume test tree): a test of two nodes stands
    /// for every pair of their items, so the upper levels are tested once for all, not once per
    /// query. The walk's first levels are done here and its front is shared out to threads.
    pub fn overlapping_pairs<T: Send>(
        &self,
        other: Option<&Bvh>,
        emit: impl Fn(u32, u32, &mut Vec<T>) -> bool + Sync,
        out: &mut Vec<T>,
        scratch: &mut WalkScratch<T>,
    ) -> (u64, u64) {
        out.clear();
        let b = other.unwrap_or(self);
        if self.nodes.is_empty() || b.nodes.is_empty() {
            return (0, 0);
        }
        let same = other.is_none();
        if !same && !self.nodes[0].bounds.overlaps(&b.nodes[0].bounds) {
            return (1, 0);
        }
        let root = Walk {
            a: self.wide_root,
            b: b.wide_root,
            same,
        };
        let WalkScratch { front, stack, runs } = scratch;
        front.clear();
        let limit = Some(FRONT_DEPTH);
        let mut counts = self.walk(b, root, limit, front, &emit, out, stack);
        counts.0 += !same as u64;
        // A few runs of the front a thread, each walked into one buffer with one stack: a
        // buffer and a stack a node pair of the front cost more than the walk below many of
        // them. The runs come back in the front's order, so the output does not depend on
        // how the front was cut. The buffers are kept from walk to walk: grown afresh each
        // time, the large ones were the kernel's to zero page by page.
        let run = front
            .len()
            .div_ceil(4 * rayon::current_num_threads())
            .max(1);
        let n = front.len().div_ceil(run);
        if runs.len() < n {
            runs.resize_with(n, Default::default);
        }
        let (tested, looked) = front
            .par_chunks(run)
            .zip(runs[..n].par_iter_mut())
            .map(|(ws, (found, stack))| {
                found.clear();
                let mut counts = (0, 0);
                for &w in ws {
                    let c = self.walk(b, w, None, &mut Vec::new(), &emit, found, stack);
                    counts = (counts.0 + c.0, counts.1 + c.1);
                }
                counts
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        for (found, _) in &mut runs[..n] {
            out.append(found);
        }
        (counts.0 + tested, counts.1 + looked)
    }

    /// Calls `each` with every item whose box at the last refit overlaps `query` (closed boxes,
    /// the same test as [`Bvh::overlapping_pairs`], so an item found here is an item that walk
    /// pairs with `query`'s owner). Returns how many boxes it tested. Allocates nothing.
    pub fn overlapping(&self, query: &Aabb, mut each: impl FnMut(u32)) -> u64 {
        if self.nodes.is_empty() {
            return 0;
        }
        let q = Lanes::of(query);
        // Median splits halve the items at every level: a stack of 64 holds any tree of
        // up to 2^64 items.
        let mut stack = [0u32; 64];
        let (mut top, mut tested) = (1usize, 0u64);
        while top > 0 {
            top -= 1;
            let at = stack[top];
            let node = &self.nodes[at as usize];
            tested += 1;
            if !node.bounds.overlaps(&q) {
                continue;
            }
            if node.count > 0 {
                let mut hits = self.quads[node.quad as usize].overlapping(&q);
                while hits != 0 {
                    let k = hits.trailing_zeros();
                    hits &= hits - 1;
                    each(self.order[(node.index + k) as usize]);
                }
            } else {
                (stack[top], stack[top + 1]) = (node.index, at + 1);
                top += 2;
            }
        }
        tested
    }

    /// Walks the child pairs below `root` (of `self` and `b`, whose boxes overlap), depth
    /// first, on `stack` (left empty); pairs at `limit` levels below it go to `front` instead
    /// of being opened. A pair of wide nodes tests each child of one against the other's four
    /// in one compare; a leaf against a wide node tests its box against the four.
    // Each argument is a separate input of the walk.
    #[allow(clippy::too_many_arguments)]
    fn walk<T>(
        &self,
        b: &Bvh,
        root: Walk,
        limit: Option<usize>,
        front: &mut Vec<Walk>,
        emit: &impl Fn(u32, u32, &mut Vec<T>) -> bool,
        out: &mut Vec<T>,
        stack: &mut Vec<(Walk, usize)>,
    ) -> (u64, u64) {
        stack.clear();
        stack.push((root, 0usize));
        let (mut tested, mut looked) = (0u64, 0u64);
        while let Some((w, depth)) = stack.pop() {
            if limit == Some(depth) {
                front.push(w);
                continue;
            }
            let next = depth + 1;
            let (leaf_a, leaf_b) = (w.a & LEAF_BIT != 0, w.b & LEAF_BIT != 0);
            if w.same {
                if leaf_a {
                    let na = &self.nodes[(w.a & !LEAF_BIT) as usize];
                    let range = na.index as usize..(na.index + na.count) as usize;
                    let quad = &self.quads[na.quad as usize];
                    let items = &self.order[range.clone()];
                    for (p, box_p) in self.leaf_boxes[range].iter().enumerate() {
                        tested += 1;
                        // The items after `p` only: each pair once.
                        let mut hits = quad.overlapping(box_p) & !((2u32 << p) - 1);
                        while hits != 0 {
                            let q = hits.trailing_zeros() as usize;
                            hits &= hits - 1;
                            looked += emit(items[p], items[q], out) as u64;
                        }
                    }
                } else {
                    let node = &self.wide[w.a as usize];
                    let n = node.count as usize;
                    // Pushed backwards, so the children come off the stack in order.
                    for i in (0..n).rev() {
                        let box_i = &self.nodes[node.binary[i] as usize].bounds;
                        tested += (n - 1 - i) as u64;
                        let mut hits = node.boxes.overlapping(box_i) & !((2u32 << i) - 1);
                        let mut pairs = [0u32; 4];
                        let mut found = 0;
                        while hits != 0 {
                            pairs[found] = hits.trailing_zeros();
                            found += 1;
                            hits &= hits - 1;
                        }
                        for &j in pairs[..found].iter().rev() {
                            let (a, b) = (node.child[i], node.child[j as usize]);
                            stack.push((Walk::across(a, b), next));
                        }
                        let a = node.child[i];
                        stack.push((
                            Walk {
                                a,
                                b: a,
                                same: true,
                            },
                            next,
                        ));
                    }
                }
                continue;
            }
            match (leaf_a, leaf_b) {
                (true, true) => {
                    let na = &self.nodes[(w.a & !LEAF_BIT) as usize];
                    let nb = &b.nodes[(w.b & !LEAF_BIT) as usize];
                    let ra = na.index as usize..(na.index + na.count) as usize;
                    let rb = nb.index as usize..(nb.index + nb.count) as usize;
                    let (ia, ib) = (&self.order[ra.clone()], &b.order[rb]);
                    let quad = &b.quads[nb.quad as usize];
                    for (p, box_a) in self.leaf_boxes[ra].iter().enumerate() {
                        tested += 1;
                        let mut hits = quad.overlapping(box_a);
                        while hits != 0 {
                            let q = hits.trailing_zeros() as usize;
                            hits &= hits - 1;
                            looked += emit(ia[p], ib[q], out) as u64;
                        }
                    }
                }
                (true, false) => {
                    let box_a = &self.nodes[(w.a & !LEAF_BIT) as usize].bounds;
                    let node = &b.wide[w.b as usize];
                    tested += node.count as u64;
                    for c in node.overlapping(box_a) {
                        stack.push((Walk::across(w.a, c), next));
                    }
                }
                (false, true) => {
                    let box_b = &b.nodes[(w.b & !LEAF_BIT) as usize].bounds;
                    let node = &self.wide[w.a as usize];
                    tested += node.count as u64;
                    for c in node.overlapping(box_b) {
                        stack.push((Walk::across(c, w.b), next));
                    }
                }
                (false, false) => {
                    let (na, nb) = (&self.wide[w.a as usize], &b.wide[w.b as usize]);
                    for i in 0..na.count as usize {
                        let box_i = &self.nodes[na.binary[i] as usize].bounds;
                        tested += nb.count as u64;
                        for c in nb.overlapping(box_i) {
                            stack.push((Walk::across(na.child[i], c), next));
                        }
                    }
                }
            }
        }
        (tested, looked)
    }

    pub fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * size_of::<Node>()
            + self.order.capacity() * 4
            + self.quads.capacity() * size_of::<Quad>()
            + self.leaf_boxes.capacity() * size_of::<Lanes>()
            + self.wide.capacity() * size_of::<Wide>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(c: Vec3, r: f32) -> Aabb {
        Aabb {
            min: c - Vec3::splat(r),
            max: c + Vec3::splat(r),
        }
    }

    /// Boxes scattered in `[-2, 2]^3`, of several sizes, moved by `t`.
    fn scattered(count: usize, t: f32) -> Vec<Aabb> {
        (0..count)
            .map(|k| {
                let f = k as f32;
                let c = Vec3::new((f * 0.37 + t).sin(), (f * 0.11).cos(), (f * 0.73 - t).sin());
                cube(2.0 * c, 0.05 + 0.1 * ((f * 1.3).sin().abs()))
            })
            .collect()
    }

    /// The simultaneous walk must report exactly the overlapping pairs a brute-force test
    /// finds, each once: between two trees, and within one tree (no item with itself).
    #[test]
    fn every_overlapping_pair_is_found_once_between_trees_and_within_one() {
        let (mut first, mut second) = (Bvh::default(), Bvh::default());
        let a = scattered(700, 0.0);
        let b = scattered(500, 2.9);
        first.build(&scattered(700, 0.4));
        second.build(&b);
        first.refit(&a);
        let emit = |i: u32, j: u32, out: &mut Vec<(u32, u32)>| {
            out.push((i, j));
            true
        };
        let (mut found, mut scratch) = (Vec::new(), WalkScratch::default());
        let (_, looked) = first.overlapping_pairs(Some(&second), emit, &mut found, &mut scratch);
        assert_eq!(looked as usize, found.len());
        found.sort_unstable();
        let brute: Vec<(u32, u32)> = (0..a.len() as u32)
            .flat_map(|i| (0..b.len() as u32).map(move |j| (i, j)))
            .filter(|&(i, j)| a[i as usize].overlaps(&b[j as usize]))
            .collect();
        assert!(brute.len() > 100, "too few pairs to test: {}", brute.len());
        assert_eq!(found, brute);
        let ordered = |i: u32, j: u32, out: &mut Vec<(u32, u32)>| {
            out.push((i.min(j), i.max(j)));
            true
        };
        first.overlapping_pairs(None, ordered, &mut found, &mut scratch);
        found.sort_unstable();
        let brute: Vec<(u32, u32)> = (0..a.len() as u32)
            .flat_map(|i| (i + 1..a.len() as u32).map(move |j| (i, j)))
            .filter(|&(i, j)| a[i as usize].overlaps(&a[j as usize]))
            .collect();
        assert_eq!(found, brute);
    }

    /// A query by one box finds exactly the items the walk of two trees pairs it with.
    #[test]
    fn one_box_finds_what_the_walk_pairs_it_with() {
        let (mut tree, mut one) = (Bvh::default(), Bvh::default());
        let boxes = scattered(700, 0.0);
        tree.build(&boxes);
        for query in scattered(60, 1.7) {
            one.build(&[query]);
            let emit = |_: u32, j: u32, out: &mut Vec<u32>| {
                out.push(j);
                true
            };
            let mut walked = Vec::new();
            one.overlapping_pairs(Some(&tree), emit, &mut walked, &mut Default::default());
            let mut found = Vec::new();
            assert!(tree.overlapping(&query, |j| found.push(j)) > 0);
            walked.sort_unstable();
            found.sort_unstable();
            assert_eq!(found, walked);
        }
        assert_eq!(Bvh::default().overlapping(&boxes[0], |_| panic!()), 0);
    }

    /// The wide tree's edge cases (a single leaf for a root, wide nodes of two to four
    /// children, leaves against wide nodes) find the brute-force pairs at every small size.
    #[test]
    fn every_overlapping_pair_is_found_in_trees_of_every_small_size() {
        let emit = |i: u32, j: u32, out: &mut Vec<(u32, u32)>| {
            out.push((i.min(j), i.max(j)));
            true
        };
        for n in 1..40 {
            let a = scattered(n, 0.3);
            let (mut tree, mut other) = (Bvh::default(), Bvh::default());
            tree.build(&a);
            let mut found = Vec::new();
            tree.overlapping_pairs(None, emit, &mut found, &mut Default::default());
            found.sort_unstable();
            let brute: Vec<(u32, u32)> = (0..n as u32)
                .flat_map(|i| (i + 1..n as u32).map(move |j| (i, j)))
                .filter(|&(i, j)| a[i as usize].overlaps(&a[j as usize]))
                .collect();
            assert_eq!(found, brute, "{n} items against themselves");
            let b = scattered(41 - n, 1.1);
            other.build(&b);
            let across = |i: u32, j: u32, out: &mut Vec<(u32, u32)>| {
                out.push((i, j));
                true
            };
            tree.overlapping_pairs(Some(&other), across, &mut found, &mut Default::default());
            found.sort_unstable();
            let brute: Vec<(u32, u32)> = (0..n as u32)
                .flat_map(|i| (0..b.len() as u32).map(move |j| (i, j)))
                .filter(|&(i, j)| a[i as usize].overlaps(&b[j as usize]))
                .collect();
            assert_eq!(found, brute, "{n} items against {}", b.len());
        }
    }

    #[test]
    fn an_empty_tree_finds_nothing() {
        let mut tree = Bvh::default();
        tree.build(&[]);
        assert!(tree.is_built_for(0));
        let mut found: Vec<()> = Vec::new();
        let never = |_, _, _: &mut Vec<()>| -> bool { panic!() };
        assert_eq!(
            tree.overlapping_pairs(None, never, &mut found, &mut Default::default()),
            (0, 0)
        );
    }
}
