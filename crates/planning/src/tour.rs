//! Tour sequencing: the order of the selected measurements that minimises the campaign time.
//!
//! # Cost model
//! The robot visits the measurements one after the other; between two measurements it moves
//! between their retreat poses. The cost of going from measurement `i` to `j` is
//!
//! `c(i, j) = t_move(i, j) + T_replace · [position_i ≠ position_j]`
//!
//! with `t_move` the synchronised joint-move time ([`crate::motion::MotionTimer`]) and
//! `T_replace` the time of a manual re-placement of the probe plate. The problem is an *open*
//! path (it ends at the last measurement) that optionally starts from a given configuration
//! (cost `t_move(start, j)` to the first measurement; the first placement of the plate is part
//! of the set-up and costs nothing). Because `T_replace` is much larger than any move, the
//! optimum visits each calibration position in one block, with exactly (positions − 1)
//! re-placements; the order of the blocks is optimised as well. The per-measurement times
//! (auto-centring, approach and retreat) do not depend on the order and are added afterwards.
//!
//! # Heuristic ([`solve_open_path`])
//! Seeded restarts of: nearest-neighbour construction from a random first node (restart 0
//! starts from the input order instead, so the result is never worse than the input), then
//! local search until no move improves: **2-opt** (reverse a sub-sequence), **Or-opt** (move a
//! run of 1–3 consecutive measurements elsewhere, possibly reversed) and, when the measurements
//! form contiguous position blocks (at most 5), **block reordering** (every order and direction
//! of the blocks). The best tour over all restarts is returned.
//!
//! [`held_karp`] solves small instances (n ≤ 16) exactly by dynamic programming over subsets;
//! it is the reference of the tests.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

/// A symmetric cost matrix between `n` nodes plus the cost from an optional start to each node.
#[derive(Debug, Clone, PartialEq)]
pub struct TourCosts {
    n: usize,
    /// row-major n × n
    cost: Vec<f64>,
    /// cost from the start to each node (zeros when the tour starts anywhere)
    start: Vec<f64>,
}

impl TourCosts {
    /// Builds the costs from a function `cost(i, j)` (must be symmetric) and an optional start
    /// cost `start(j)`.
    pub fn new(n: usize, cost: impl Fn(usize, usize) -> f64, start: Option<&dyn Fn(usize) -> f64>) -> Self {
        let mut c = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    c[i * n + j] = cost(i, j);
                }
            }
        }
        let start = (0..n).map(|j| start.map_or(0.0, |f| f(j))).collect();
        Self { n, cost: c, start }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True when there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Cost of the edge i → j.
    #[inline]
    pub fn cost(&self, i: usize, j: usize) -> f64 {
        self.cost[i * self.n + j]
    }

    /// Cost from the start to node j.
    #[inline]
    pub fn start_cost(&self, j: usize) -> f64 {
        self.start[j]
    }

    /// Total cost of visiting `order` (start → `order[0]` → ... → `order[n-1]`).
    pub fn path_cost(&self, order: &[usize]) -> f64 {
        match order.first() {
            None => 0.0,
            Some(&f) => self.start_cost(f) + order.windows(2).map(|w| self.cost(w[0], w[1])).sum::<f64>(),
        }
    }

    /// Edge cost with sentinels: `None` before the first node is the start, `None` after the
    /// last node is the free end.
    #[inline]
    fn edge(&self, a: Option<usize>, b: Option<usize>) -> f64 {
        match (a, b) {
            (Some(a), Some(b)) => self.cost(a, b),
            (None, Some(b)) => self.start_cost(b),
            _ => 0.0,
        }
    }
}

/// Options of the tour heuristic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TourOptions {
    /// number of restarts (≥ 1; restart 0 improves the input order)
    pub restarts: usize,
    /// seed of the restarts
    pub seed: u64,
}

impl Default for TourOptions {
    fn default() -> Self {
        Self { restarts: 16, seed: 1 }
    }
}

/// Best open path found by the heuristic: a permutation of `0..n` never costlier than the
/// identity (input) order. `groups[i]` is the calibration position of node i (used only by the
/// block-reordering move; the costs already contain the re-placement times).
pub fn solve_open_path(costs: &TourCosts, groups: &[u32], opts: &TourOptions) -> Vec<usize> {
    let n = costs.len();
    if n <= 1 {
        return (0..n).collect();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut best: Vec<usize> = (0..n).collect();
    local_search(costs, groups, &mut best);
    let mut best_cost = costs.path_cost(&best);
    for _ in 1..opts.restarts.max(1) {
        let first = rng.random_range(0..n);
        let mut order = nearest_neighbour(costs, first);
        local_search(costs, groups, &mut order);
        let c = costs.path_cost(&order);
        if c < best_cost - 1e-12 {
            best = order;
            best_cost = c;
        }
    }
    best
}

/// Nearest-neighbour construction from `first`.
pub fn nearest_neighbour(costs: &TourCosts, first: usize) -> Vec<usize> {
    let n = costs.len();
    let mut visited = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut current = first;
    visited[current] = true;
    order.push(current);
    for _ in 1..n {
        let next = (0..n)
            .filter(|j| !visited[*j])
            .min_by(|a, b| costs.cost(current, *a).total_cmp(&costs.cost(current, *b)))
            .unwrap_or(current);
        visited[next] = true;
        order.push(next);
        current = next;
    }
    order
}

/// 2-opt, Or-opt and block reordering until no move improves (first-improvement).
pub fn local_search(costs: &TourCosts, groups: &[u32], order: &mut Vec<usize>) {
    let mut guard = 0;
    loop {
        guard += 1;
        let improved = two_opt(costs, order) || or_opt(costs, order) || reorder_blocks(costs, groups, order);
        if !improved || guard > 10_000 {
            break;
        }
    }
}

const EPS: f64 = 1e-9;

fn at(order: &[usize], k: isize) -> Option<usize> {
    if k < 0 { None } else { order.get(k as usize).copied() }
}

/// One improving 2-opt move (reverse order[i..=j]), if any.
fn two_opt(costs: &TourCosts, order: &mut [usize]) -> bool {
    let n = order.len() as isize;
    for i in 0..n - 1 {
        for j in i + 1..n {
            let (p, a, b, nx) = (at(order, i - 1), at(order, i), at(order, j), at(order, j + 1));
            let before = costs.edge(p, a) + costs.edge(b, nx);
            let after = costs.edge(p, b) + costs.edge(a, nx);
            if after < before - EPS {
                order[i as usize..=j as usize].reverse();
                return true;
            }
        }
    }
    false
}

/// One improving Or-opt move (a run of 1..=3 moved elsewhere, possibly reversed), if any.
fn or_opt(costs: &TourCosts, order: &mut Vec<usize>) -> bool {
    let n = order.len();
    for len in 1..=3.min(n - 1) {
        for i in 0..=n - len {
            let (first, last) = (order[i], order[i + len - 1]);
            let p = at(order, i as isize - 1);
            let nx = at(order, (i + len) as isize);
            let removal_gain = costs.edge(p, Some(first)) + costs.edge(Some(last), nx) - costs.edge(p, nx);
            // insertion between rest[k-1] and rest[k] of the sequence without the run
            let rest: Vec<usize> = order[..i].iter().chain(&order[i + len..]).copied().collect();
            for k in 0..=rest.len() {
                if k == i {
                    continue; // same place
                }
                let a = at(&rest, k as isize - 1);
                let b = rest.get(k).copied();
                let base = costs.edge(a, b);
                let forward = costs.edge(a, Some(first)) + costs.edge(Some(last), b) - base;
                let backward = costs.edge(a, Some(last)) + costs.edge(Some(first), b) - base;
                let (add, reversed) = if backward < forward { (backward, true) } else { (forward, false) };
                if add < removal_gain - EPS {
                    let mut run: Vec<usize> = order[i..i + len].to_vec();
                    if reversed {
                        run.reverse();
                    }
                    let mut next = rest[..k].to_vec();
                    next.extend(run);
                    next.extend_from_slice(&rest[k..]);
                    *order = next;
                    return true;
                }
            }
        }
    }
    false
}

/// When the tour is made of contiguous blocks of equal group (≤ 5 blocks, each group once),
/// tries every order and direction of the blocks; applies the best if it improves.
fn reorder_blocks(costs: &TourCosts, groups: &[u32], order: &mut Vec<usize>) -> bool {
    if groups.len() != costs.len() {
        return false;
    }
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    for &node in order.iter() {
        match blocks.last_mut() {
            Some(b) if groups[b[0]] == groups[node] => b.push(node),
            _ => blocks.push(vec![node]),
        }
    }
    let k = blocks.len();
    if !(2..=5).contains(&k) {
        return false;
    }
    let mut seen: Vec<u32> = blocks.iter().map(|b| groups[b[0]]).collect();
    seen.sort_unstable();
    seen.dedup();
    if seen.len() != k {
        return false;
    }
    let current = costs.path_cost(order);
    let mut best: Option<(f64, Vec<usize>)> = None;
    let mut perm: Vec<usize> = (0..k).collect();
    loop {
        for dirs in 0..(1u32 << k) {
            let mut candidate = Vec::with_capacity(order.len());
            for (slot, &b) in perm.iter().enumerate() {
                if dirs & (1 << slot) != 0 {
                    candidate.extend(blocks[b].iter().rev());
                } else {
                    candidate.extend(&blocks[b]);
                }
            }
            let c = costs.path_cost(&candidate);
            if c < current - EPS && best.as_ref().is_none_or(|(bc, _)| c < *bc) {
                best = Some((c, candidate));
            }
        }
        if !next_permutation(&mut perm) {
            break;
        }
    }
    match best {
        Some((_, b)) => {
            *order = b;
            true
        }
        None => false,
    }
}

/// Lexicographic next permutation; false when `p` was the last one.
fn next_permutation(p: &mut [usize]) -> bool {
    let n = p.len();
    if n < 2 {
        return false;
    }
    let mut i = n - 1;
    while i > 0 && p[i - 1] >= p[i] {
        i -= 1;
    }
    if i == 0 {
        return false;
    }
    let mut j = n - 1;
    while p[j] <= p[i - 1] {
        j -= 1;
    }
    p.swap(i - 1, j);
    p[i..].reverse();
    true
}

/// Exact optimum of the open path (Held–Karp dynamic programming, O(2^n n^2)); `None` when
/// `n > 16`.
pub fn held_karp(costs: &TourCosts) -> Option<(f64, Vec<usize>)> {
    let n = costs.len();
    if n > 16 {
        return None;
    }
    if n == 0 {
        return Some((0.0, Vec::new()));
    }
    let full = (1usize << n) - 1;
    let mut dp = vec![f64::INFINITY; (full + 1) * n];
    let mut parent = vec![usize::MAX; (full + 1) * n];
    for j in 0..n {
        dp[(1 << j) * n + j] = costs.start_cost(j);
    }
    for mask in 1..=full {
        for j in 0..n {
            let cur = dp[mask * n + j];
            if mask & (1 << j) == 0 || !cur.is_finite() {
                continue;
            }
            for k in 0..n {
                if mask & (1 << k) != 0 {
                    continue;
                }
                let next = mask | (1 << k);
                let c = cur + costs.cost(j, k);
                if c < dp[next * n + k] {
                    dp[next * n + k] = c;
                    parent[next * n + k] = j;
                }
            }
        }
    }
    let (mut last, best) = (0..n).map(|j| (j, dp[full * n + j])).min_by(|a, b| a.1.total_cmp(&b.1))?;
    let mut order = vec![last];
    let mut mask = full;
    while parent[mask * n + last] != usize::MAX {
        let p = parent[mask * n + last];
        mask &= !(1 << last);
        last = p;
        order.push(last);
    }
    order.reverse();
    Some((best, order))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permutations_are_enumerated() {
        let mut p = vec![0, 1, 2, 3];
        let mut count = 1;
        while next_permutation(&mut p) {
            count += 1;
        }
        assert_eq!(count, 24);
        assert_eq!(p, vec![3, 2, 1, 0]);
    }
}
