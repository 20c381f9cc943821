//! A mesh a cut cannot split consistently is refused with the face and the tets named, so that
//! a user can find them (in a written VTU, whose points and cells are numbered the same way).

use lancet::cut::{CutMethod, Cutter};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, SpringModel};
use lancet::Error;

/// A box with one tet listed twice (as Gmsh 2.2 repeats an element of two physical groups,
/// had the reader not merged it): every face of that tet has a third tet. The error once named
/// neither face nor tets.
#[test]
fn a_duplicated_tet_is_refused_naming_the_face_and_the_tets() {
    let mut mesh = BoxGrid::cube_cells([2, 2, 2], 0.01).build().unwrap();
    let copied = 5;
    let tet = *mesh.tets().nth(copied).unwrap().1;
    mesh.add_tet(tet.nodes, tet.region).unwrap();
    let copy = mesh.tet_count() - 1;
    let model = SpringModel::build(
        &mesh,
        &ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0)),
    )
    .unwrap();
    let corners = {
        let dense = mesh.dense_nodes();
        tet.nodes.map(|k| dense.index[k] as usize)
    };
    for method in [CutMethod::Separate, CutMethod::Subdivide] {
        let err = Cutter::new(mesh.clone(), model.clone(), method).unwrap_err();
        let msg = err.to_string();
        match err {
            Error::NonManifold { face, tets } => {
                assert!(tets.contains(&copied) && tets.contains(&copy), "{msg}");
                assert!(tets.len() >= 3, "{msg}");
                assert!(face.iter().all(|n| corners.contains(n)), "{msg}");
                assert!(msg.contains(&format!("{face:?}")), "{msg}");
                assert!(msg.contains(&copy.to_string()), "{msg}");
            }
            other => panic!("{method}: expected a non-manifold face, got {other}"),
        }
    }
}
