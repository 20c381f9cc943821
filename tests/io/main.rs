//! Reading and writing meshes: every format, hostile input, topology.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

mod features;
mod gmsh_writers;
mod io_bombs;
mod io_duplicates;
mod io_formats;
mod io_formats_robust;
mod io_gmsh;
mod io_messages;
mod io_vtu;
mod mesh_topology;
mod readers_never_panic;
