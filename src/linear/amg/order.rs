//! A local order of a graph's nodes: the order greedy aggregation visits a matrix's nodes in
//! (`aggregate.rs`), and the order a mesh cloth's force pass numbers its vertices in where the
//! user's numbering is scattered ([`crate::scene::MeshCloth`]).

/// Each node's place in `order` (`place[order[k]] = k`; nodes not in it at 0), for `n` nodes.
pub fn places(order: &[u32], n: usize) -> Vec<u32> {
    let mut place = vec![0u32; n];
    for (k, &v) in order.iter().enumerate() {
        place[v as usize] = k as u32;
    }
    place
}

/// The `free` nodes of a graph (node `v`'s neighbours `neighbours[offsets[v]..offsets[v + 1]]`,
/// all free, each edge listed at both ends) in a local order: their numbering, or where that
/// is scattered ([`breadth_first`] puts the edges' ends closer together: the sum over the
/// edges of how far apart their ends are placed is smaller), a breadth-first order.
pub fn local_order(free: &[bool], offsets: &[usize], neighbours: &[u32]) -> Vec<u32> {
    let n = free.len();
    let numbering: Vec<u32> = (0..n as u32).filter(|&v| free[v as usize]).collect();
    let bfs = breadth_first(free, offsets, neighbours);
    let spread = |order: &[u32]| {
        let place = places(order, n);
        (0..n)
            .flat_map(|v| {
                neighbours[offsets[v]..offsets[v + 1]]
                    .iter()
                    .map(move |&c| (v, c))
            })
            .map(|(v, c)| place[v].abs_diff(place[c as usize]) as u64)
            .sum::<u64>()
    };
    if spread(&bfs) < spread(&numbering) {
        bfs
    } else {
        numbering
    }
}

/// The free nodes in a Cuthill-McKee order of the graph ([`local_order`]): breadth first,
/// each node's unvisited neighbours taken fewest connections first, one connected component
/// after another, each from a pseudo-peripheral node (the last node a first search from its
/// lowest-numbered node reaches), so that the front crosses the component from one side
/// rather than spreading from wherever the numbering begins it (both choices measured in
/// docs/notes/mesh_cloth.md, "Speed, as first measured, and vertex order").
fn breadth_first(free: &[bool], offsets: &[usize], neighbours: &[u32]) -> Vec<u32> {
    const UNSEEN: u8 = 0;
    const PROBED: u8 = 1;
    const PLACED: u8 = 2;
    let n = free.len();
    let degree = |c: u32| offsets[c as usize + 1] - offsets[c as usize];
    let mut mark = vec![UNSEEN; n];
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut probe: Vec<u32> = Vec::new();
    // Appends to `list` the nodes reached from `list[from..]` whose mark is `seen`, marked
    // `reached`, breadth first.
    let search = |list: &mut Vec<u32>, from: usize, mark: &mut [u8], seen: u8, reached: u8| {
        let mut k = from;
        while k < list.len() {
            let v = list[k] as usize;
            k += 1;
            let first = list.len();
            for &c in &neighbours[offsets[v]..offsets[v + 1]] {
                if mark[c as usize] == seen {
                    mark[c as usize] = reached;
                    list.push(c);
                }
            }
            list[first..].sort_by_key(|&c| (degree(c), c));
        }
    };
    for s in 0..n {
        if !free[s] || mark[s] != UNSEEN {
            continue;
        }
        probe.clear();
        probe.push(s as u32);
        mark[s] = PROBED;
        search(&mut probe, 0, &mut mark, UNSEEN, PROBED);
        let start = *probe.last().expect("the search's first node");
        let from = order.len();
        order.push(start);
        mark[start as usize] = PLACED;
        search(&mut order, from, &mut mark, PROBED, PLACED);
    }
    order
}
