// The node-centric layouts' walk for `implicit_solve.wgsl` (connectivity, valence): a node's
// springs (or tensor blocks) are the slots of its row. Followed by the force model's product
// (implicit_slots_springs.wgsl, implicit_slots_tensor.wgsl) and the layout's `row_of`
// (implicit_connectivity.wgsl, implicit_valence.wgsl). The twin is `twin::implicit_solve::rows`
// (`twin::implicit_tensor::tensor_rows` for the blocks).

// Where a node's slots start and how many its row holds (width 0: no slots).
struct Row {
    base: u32,
    width: u32,
}

// A walk over node i's slots as `node_gather.wgsl` walks them: stopping at an empty slot, going
// on in row `pad` (of the connectivity table's width) at a CONTINUE slot.
struct Cursor {
    base: u32,
    width: u32,
    s: u32,
    hops: u32,
}

fn cursor(i: u32) -> Cursor {
    let row = row_of(i);
    return Cursor(row.base, row.width, 0u, 0u);
}

// The index of the next real slot of the walk, EMPTY at its end.
fn advance(c: ptr<function, Cursor>) -> u32 {
    loop {
        if ((*c).s >= (*c).width) {
            return EMPTY;
        }
        let slot = slots[(*c).base + (*c).s];
        if (slot.other == EMPTY) {
            return EMPTY;
        }
        if (slot.other == CONTINUE) {
            (*c).hops = (*c).hops + 1u;
            if ((*c).hops > q.n) {
                return EMPTY;
            }
            // Only the connectivity layout continues rows, always in rows of its width.
            (*c).base = slot.pad * q.width;
            (*c).width = q.width;
            (*c).s = 0u;
            continue;
        }
        let index = (*c).base + (*c).s;
        (*c).s = (*c).s + 1u;
        return index;
    }
    return EMPTY;
}

// The next spring of the walk, as seen from node i; `other == EMPTY` at its end.
fn next_slot(c: ptr<function, Cursor>) -> Slot {
    let k = advance(c);
    if (k == EMPTY) {
        return Slot(vec3<f32>(0.0), 0.0, 0.0, 0.0, EMPTY, 0u);
    }
    return slots[k];
}
