//! The merged regions as a graph: which regions share cell edges, and how
//! many. The rules that use the instrument's shape (growth into what borders
//! it, no holes, one object) work on this graph, a few hundred regions,
//! instead of flooding the grid of cells. A merged region is 4-connected
//! (regions merge only across a shared cell edge), so the components and
//! holes of the graph are those of the cells.

use super::Scratch;

/// Builds the graph of the merged regions (roots of `s.parent`) from the
/// leaf pairs the merge recorded (`s.leaf_edges`, which become the pairs of
/// different regions): for each region, its
/// neighbours and the cell edges it shares with each (a neighbour may be
/// listed more than once; the counts add up), in `s.adjacency` from
/// `s.adjacency_start[r]` to `s.adjacency_start[r + 1]`. Marks in
/// `s.on_border` the regions with a cell on the region of interest's edge.
pub(super) fn build(s: &mut Scratch, cols: usize, rows: usize) {
    let Scratch {
        leaf_edges,
        parent,
        adjacency,
        adjacency_start,
        on_border,
        leaf_box,
        ..
    } = s;
    let n = parent.len();
    // the leaf pairs become region pairs; pairs within one region go
    // (most of them: the merge joined them)
    leaf_edges.retain_mut(|e| {
        let (a, b) = (parent[e[0] as usize], parent[e[1] as usize]);
        *e = [a, b, e[2]];
        a != b
    });
    adjacency_start.clear();
    adjacency_start.resize(n + 1, 0);
    for e in leaf_edges.iter() {
        adjacency_start[e[0] as usize + 1] += 1;
        adjacency_start[e[1] as usize + 1] += 1;
    }
    for i in 0..n {
        adjacency_start[i + 1] += adjacency_start[i];
    }
    adjacency.clear();
    adjacency.resize(adjacency_start[n] as usize, [0, 0]);
    // fill from each region's start, then shift the starts back
    for &[a, b, edges] in leaf_edges.iter() {
        for (from, to) in [(a, b), (b, a)] {
            let slot = &mut adjacency_start[from as usize];
            adjacency[*slot as usize] = [to, edges];
            *slot += 1;
        }
    }
    for i in (1..=n).rev() {
        adjacency_start[i] = adjacency_start[i - 1];
    }
    adjacency_start[0] = 0;
    on_border.clear();
    on_border.resize(n, false);
    for (leaf, b) in leaf_box.iter().enumerate() {
        if b[0] == 0 || b[1] == 0 || b[2] as usize + 1 >= cols || b[3] as usize + 1 >= rows {
            on_border[parent[leaf] as usize] = true;
        }
    }
}

/// The neighbours of region `r` and the cell edges shared with each.
#[inline]
pub(super) fn neighbours<'a>(
    adjacency: &'a [[u32; 2]],
    adjacency_start: &[u32],
    r: usize,
) -> &'a [[u32; 2]] {
    &adjacency[adjacency_start[r] as usize..adjacency_start[r + 1] as usize]
}

/// Marks as instrument every tissue region that no chain of tissue regions
/// links to the region of interest's edge: holes in the instrument. The
/// instrument's silhouette has none (a bent tube and its jaws enclose no
/// tissue), so a hole is steel the threshold missed (a disc reflecting the
/// tissue, a highlight's rim). `roots` are the merged regions.
pub(super) fn fill_holes(s: &mut Scratch) {
    let Scratch {
        instrument,
        adjacency,
        adjacency_start,
        on_border,
        roots,
        seen,
        flood,
        ..
    } = s;
    seen.clear();
    seen.resize(instrument.len(), false);
    flood.clear();
    for &r in roots.iter() {
        let r = r as usize;
        if instrument[r] == 0 && on_border[r] {
            seen[r] = true;
            flood.push(r);
        }
    }
    while let Some(r) = flood.pop() {
        for &[o, _] in neighbours(adjacency, adjacency_start, r) {
            let o = o as usize;
            if instrument[o] == 0 && !seen[o] {
                seen[o] = true;
                flood.push(o);
            }
        }
    }
    for &r in roots.iter() {
        let r = r as usize;
        if instrument[r] == 0 && !seen[r] {
            instrument[r] = 1;
        }
    }
}

/// Clears the instrument's connected components that hold fewer than `min`
/// pixels or fewer than `share_of_total` times all the components' pixels
/// together (the largest stays, whatever the share). Returns the pixels left.
pub(super) fn keep_components(s: &mut Scratch, min: f32, share_of_total: f32) -> usize {
    let Scratch {
        instrument,
        regions,
        adjacency,
        adjacency_start,
        roots,
        seen,
        flood,
        component,
        component_spans: spans,
        ..
    } = s;
    // each component: its regions in `component[start..end]` and its pixels
    // (whole numbers up to the region of interest's 2²⁴ pixels at most,
    // `MAX_ROI_PIXELS`, which an f32 holds exactly)
    seen.clear();
    seen.resize(instrument.len(), false);
    component.clear();
    spans.clear();
    let (mut total, mut largest) = (0.0f32, 0.0f32);
    for &start in roots.iter() {
        let start = start as usize;
        if instrument[start] == 0 || seen[start] {
            continue;
        }
        let first = component.len();
        flood.clear();
        flood.push(start);
        seen[start] = true;
        while let Some(r) = flood.pop() {
            component.push(r);
            for &[o, _] in neighbours(adjacency, adjacency_start, r) {
                let o = o as usize;
                if instrument[o] != 0 && !seen[o] {
                    seen[o] = true;
                    flood.push(o);
                }
            }
        }
        let pixels: f32 = component[first..].iter().map(|&r| regions[r].count).sum();
        spans.push((first, component.len(), pixels));
        total += pixels;
        largest = largest.max(pixels);
    }
    // never more than the largest: an instrument in many pieces, or a share
    // above a half, keeps its largest piece
    let least = min.max((share_of_total * total).min(largest));
    let mut kept = 0usize;
    for &(first, end, pixels) in spans.iter() {
        if pixels < least {
            for &r in &component[first..end] {
                instrument[r] = 0;
            }
        } else {
            kept += pixels as usize;
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::super::SegmentParams;
    use super::super::regions::{Region, merge};
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The merge's records and the graph built from them give, for every
    /// pair of merged regions, the cell edges a walk over the whole grid
    /// counts, and the regions on the grid's edge; on leaves of one cell and
    /// of blocks, with colours that merge some pairs and not others.
    #[test]
    fn the_graph_holds_every_shared_cell_edge_of_the_grid() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        // without noise the merge's first pass joins nothing; with it, the
        // first pass joins the pairs of equal colour (and flags their records)
        let grids = [(17usize, 11usize, 1usize), (23, 9, 3), (40, 30, 4)];
        for ((cols, rows, block), noise) in grids.iter().flat_map(|&g| [(g, 0.0), (g, 0.05)]) {
            // leaves: blocks of `block` cells, each a colour of a few
            let (bc, br) = (cols.div_ceil(block), rows.div_ceil(block));
            let mut s = Scratch {
                labels: (0..cols * rows)
                    .map(|i| ((i / cols / block) * bc + (i % cols) / block) as u32)
                    .collect(),
                regions: (0..bc * br)
                    .map(|_| {
                        let c = [0.2, 0.5, 0.8][rng.random_range(0..3)];
                        Region::of_mean([c, 0.3, 0.3], (4 * block * block) as f32)
                    })
                    .collect(),
                leaf_box: (0..bc * br)
                    .map(|l| {
                        let (x, y) = ((l % bc) * block, (l / bc) * block);
                        let (x1, y1) = ((x + block).min(cols) - 1, (y + block).min(rows) - 1);
                        [x as u32, y as u32, x1 as u32, y1 as u32]
                    })
                    .collect(),
                ..Scratch::default()
            };
            merge(&mut s, cols, rows, &SegmentParams::default(), noise);
            build(&mut s, cols, rows);
            let n = s.regions.len();
            let root = |x: usize, y: usize| s.parent[s.labels[y * cols + x] as usize] as usize;
            let mut brute = vec![0u32; n * n];
            let mut border = vec![false; n];
            for y in 0..rows {
                for x in 0..cols {
                    let a = root(x, y);
                    if x == 0 || y == 0 || x + 1 == cols || y + 1 == rows {
                        border[a] = true;
                    }
                    for (u, v) in [(x + 1, y), (x, y + 1)] {
                        if u < cols && v < rows && root(u, v) != a {
                            brute[a * n + root(u, v)] += 1;
                            brute[root(u, v) * n + a] += 1;
                        }
                    }
                }
            }
            let mut got = vec![0u32; n * n];
            for r in 0..n {
                for &[o, e] in neighbours(&s.adjacency, &s.adjacency_start, r) {
                    got[r * n + o as usize] += e;
                }
            }
            assert_eq!(
                got, brute,
                "{cols}×{rows}, blocks of {block}, noise {noise}"
            );
            assert!(got.iter().any(|&e| e > 0), "some regions stay apart");
            let roots: Vec<usize> = (0..n).filter(|&r| s.parent[r] as usize == r).collect();
            assert!(roots.len() < n, "some leaves merge");
            for r in roots {
                assert_eq!(s.on_border[r], border[r], "region {r}");
            }
        }
    }
}
