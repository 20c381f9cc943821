//! Checking a patched layout against a rebuild: after incremental updates the layout must hold
//! what packing the model from scratch gives. `lancet run --check` does this after every cut
//! on the GPU (with the device's copy of every array, see `GpuEngine::verify`).

use super::connectivity::ConnectivityLayout;
use super::edges::{EdgeLayout, B_END, NO_SPRING};
use super::valence::ValenceLayout;
use super::PackedLayout;
use crate::error::Result;
use crate::model::PackedModel;

impl PackedLayout {
    /// How this layout differs from `model` packed from scratch in the same arrangement (node
    /// order, row width, buckets and their room): empty when it agrees. The node-centric
    /// layouts must equal the rebuild exactly; the edge layout, whose patches reuse spring
    /// records and move rows, must hold the same springs, bit for bit, at every node.
    pub fn differences_from_rebuild(&self, model: &PackedModel) -> Result<Vec<String>> {
        Ok(match self {
            PackedLayout::Connectivity(c) => {
                let fresh = ConnectivityLayout::new(model, c.order.clone(), Some(c.capacity))?;
                connectivity_differences(c, &fresh)
            }
            PackedLayout::Valence(v) => {
                let fresh = ValenceLayout::arranged(
                    model,
                    v.order.clone(),
                    v.buckets.clone(),
                    v.room.clone(),
                )?;
                valence_differences(v, &fresh)
            }
            PackedLayout::Edges(e) => edge_differences(e, &EdgeLayout::new(model, e.order.clone())),
        })
    }
}

fn first_difference<T: PartialEq>(a: &[T], b: &[T]) -> Option<usize> {
    a.iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .or((a.len() != b.len()).then(|| a.len().min(b.len())))
}

fn node_arrays(what: &str, inv_mass: (&[f32], &[f32]), order: (&[u32], &[u32])) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(i) = first_difference(order.0, order.1) {
        out.push(format!(
            "{what}: node order differs from a rebuild at layout index {i}"
        ));
    }
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    if let Some(i) = first_difference(&bits(inv_mass.0), &bits(inv_mass.1)) {
        out.push(format!(
            "{what}: inverse mass differs from a rebuild at layout index {i}"
        ));
    }
    out
}

fn connectivity_differences(c: &ConnectivityLayout, fresh: &ConnectivityLayout) -> Vec<String> {
    let mut out = node_arrays(
        "connectivity layout",
        (&c.nodes.inv_mass, &fresh.nodes.inv_mass),
        (&c.order.order, &fresh.order.order),
    );
    if let Some(i) = (0..c.node_count().max(fresh.node_count())).find(|&i| c.row(i) != fresh.row(i))
    {
        out.push(format!(
            "connectivity layout: the row of layout index {i} differs from a rebuild"
        ));
    }
    out
}

fn valence_differences(v: &ValenceLayout, fresh: &ValenceLayout) -> Vec<String> {
    let mut out = node_arrays(
        "valence layout",
        (&v.nodes.inv_mass, &fresh.nodes.inv_mass),
        (&v.order.order, &fresh.order.order),
    );
    if let Some(i) = first_difference(&v.buckets, &fresh.buckets) {
        out.push(format!("valence layout: bucket {i} differs from a rebuild"));
    }
    if let Some(i) = first_difference(&v.slots, &fresh.slots) {
        out.push(format!("valence layout: slot {i} differs from a rebuild"));
    }
    out
}

/// The springs at layout index `i` of an edge layout: other end, whether the node is the `b`
/// end, and the record's bits; sorted.
fn incident(e: &EdgeLayout, i: usize) -> Vec<(u32, bool, [u32; 6])> {
    let [start, end] = e.incidence_rows[i];
    let mut out: Vec<_> = e.incidence[start as usize..end as usize]
        .iter()
        .take_while(|&&s| s != NO_SPRING)
        .map(|&s| {
            let r = e.springs[(s & !B_END) as usize];
            let is_b = s & B_END != 0;
            let other = if is_b { r.a } else { r.b };
            let bits = [r.edge[0], r.edge[1], r.edge[2], r.rest, r.k, r.c].map(f32::to_bits);
            (other, is_b, bits)
        })
        .collect();
    out.sort_unstable();
    out
}

fn edge_differences(e: &EdgeLayout, fresh: &EdgeLayout) -> Vec<String> {
    let mut out = node_arrays(
        "edge layout",
        (&e.nodes.inv_mass, &fresh.nodes.inv_mass),
        (&e.order.order, &fresh.order.order),
    );
    if e.incidence_rows.len() != fresh.incidence_rows.len() {
        out.push(format!(
            "edge layout: {} incidence rows, a rebuild has {}",
            e.incidence_rows.len(),
            fresh.incidence_rows.len()
        ));
    } else if let Some(i) =
        (0..e.incidence_rows.len()).find(|&i| incident(e, i) != incident(fresh, i))
    {
        out.push(format!(
            "edge layout: the springs at layout index {i} differ from a rebuild"
        ));
    }
    out
}
