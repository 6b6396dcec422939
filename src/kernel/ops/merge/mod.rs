//! Merge by distance and mirror (seed 000 §3.3, the *Modify* category,
//! whose examples name *mirror*; DESIGN.md pillar 1: "mirror with merge …
//! merge by distance").
//!
//! # Merge by distance
//!
//! [`merge_by_distance`] welds vertices that lie within `distance` of each
//! other. "Within distance" is not transitive, so clusters are the
//! connected components of the within-distance graph (union-find): a chain
//! of points each within `distance` of the next becomes one vertex even if
//! its ends are far apart. Each cluster keeps its **lowest-id vertex, at its
//! own position**; the others are glued onto it. Both rules depend only on
//! the set of vertices, never on visiting or input order, so permuted inputs
//! give identical meshes.
//!
//! Neighbours are found on a grid of cell size `distance` (27-cell
//! neighbourhood, visited as the cell itself plus 13 "forward" cells so each
//! pair of cells is looked at once), kept as a sorted list swept with
//! forward-only cursors: a sort plus linear work for bounded density.
//! `distance == 0` merges exactly coincident positions only, by sorting the
//! coordinates' bits (with −0 folded onto +0).
//!
//! The topology is then rewritten with Euler operators only:
//! 1. A face touching a merged vertex is *clean* when its vertices still map
//!    to distinct survivors: it simply follows the glue below and keeps its id
//!    and attributes. Otherwise it is *degenerate*: its ring and attributes
//!    are recorded and it is killed ([`Mesh::kill_face`]).
//! 2. Each merged vertex is glued onto its survivor ([`Mesh::glue_verts`]),
//!    in ascending id order. No remaining face holds two vertices of one
//!    cluster, so every glue is legal; edges between a vertex and its
//!    survivor collapse away, edges that become parallel merge (wire edges
//!    between survivors are kept).
//! 3. A clean face that now has the same vertex set as another face (two
//!    welded coincident faces) is killed, unless that other face is itself a
//!    later clean face: of twins, an untouched face wins, then the lowest id.
//! 4. Each degenerate ring, with consecutive repeats removed, is split into
//!    its simple sub-cycles; those of three or more vertices that do not
//!    duplicate an existing face are remade ([`Mesh::make_face`]) with the
//!    original face's attributes.
//!
//! `faces_removed` counts the faces that did not come back: degenerate faces
//! with no remade piece, and clean faces killed as duplicates. A face split
//! into several pieces counts as kept.
//!
//! # Mirror
//!
//! [`mirror`] duplicates a selection, reflects the copies across a plane,
//! flips their winding (a reflection turns faces inside out), and welds
//! copies to originals near the plane. On the seam the original vertex is
//! always the one kept, so the original elements keep their ids.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::delete::duplicate_mapped;
use crate::geom::UnionFind;

use super::{canonical, into_canonical, OpError, Selection};
use crate::kernel::attrs::AttrValue;
use crate::kernel::ids::{Domain, EdgeId, FaceId, VertId};
use crate::kernel::mesh::Mesh;

/// What [`merge_by_distance`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MergeResult {
    /// Vertices removed (glued onto a survivor).
    pub merged: usize,
    /// The input vertices still alive, one per cluster, sorted.
    pub survivors: Vec<VertId>,
    /// Faces that did not come back (see the module overview).
    pub faces_removed: usize,
    /// Faces made from the pieces of degenerate faces, ascending.
    pub remade: Vec<FaceId>,
}

/// Welds the given vertices that lie within `distance` of each other (see
/// the module overview). `distance` must be finite and non-negative.
pub fn merge_by_distance(
    mesh: &mut Mesh,
    verts: &[VertId],
    distance: f64,
) -> Result<MergeResult, OpError> {
    check_distance("distance", distance)?;
    let verts = canonical(verts);
    for &v in &verts {
        mesh.check_vert(v)?;
    }
    // Union by lower index and ids sorted: each root is its cluster's
    // lowest id, which is the survivor.
    let targets = cluster_roots(
        &VertPoints {
            mesh,
            verts: &verts,
        },
        distance,
    );
    weld(mesh, &verts, &targets)
}

/// Duplicates `selection`, reflects the copies across the plane through
/// `plane_point` with normal `plane_normal`, reverses their winding, then
/// merges by distance (`merge_distance`, same clusters as
/// [`merge_by_distance`]) the vertices of the selection and of the copy
/// that lie within `merge_distance` of the plane, keeping an original in
/// each cluster (the lowest id) so original ids survive. Like a
/// remove-doubles pass, this also welds originals that close to each other
/// on the seam. A copied face that comes to coincide with an original (a
/// face lying in the plane) is dropped as a duplicate.
///
/// Returns the copies still alive after the weld. (A copied face that loses
/// a corner is remade, possibly in a slot the weld freed.)
pub fn mirror(
    mesh: &mut Mesh,
    selection: &Selection,
    plane_point: DVec3,
    plane_normal: DVec3,
    merge_distance: f64,
) -> Result<Selection, OpError> {
    if !plane_point.is_finite() {
        return Err(OpError::parameter("plane_point", "must be finite"));
    }
    if !plane_normal.is_finite() {
        return Err(OpError::parameter("plane_normal", "must be finite"));
    }
    let Some(normal) = plane_normal.try_normalize() else {
        return Err(OpError::parameter("plane_normal", "must not be zero"));
    };
    check_distance("merge_distance", merge_distance)?;

    let signed = |p: DVec3| (p - plane_point).dot(normal);
    let reflect = |p: DVec3| p - 2.0 * signed(p) * normal;
    // Check every id and reflected position first, so a dead id or an
    // overflow is refused before anything is made.
    let mut touched: Vec<VertId> = selection.verts.clone();
    for &e in &selection.edges {
        mesh.check_edge(e)?;
        touched.extend(mesh.edge_verts(e));
    }
    for &f in &selection.faces {
        mesh.check_face(f)?;
        touched.extend(mesh.face_verts(f));
    }
    for v in into_canonical(touched) {
        mesh.check_vert(v)?;
        if !reflect(mesh.position(v)).is_finite() {
            return Err(OpError::parameter(
                "plane_point",
                format!("reflecting {v} overflows"),
            ));
        }
    }

    // Each copied face gets its normal once, when it is reversed below.
    let dup = duplicate_mapped(mesh, selection, false)?;
    for &(_, copy) in &dup.vert_pairs {
        let p = mesh.position(copy);
        mesh.place(copy, reflect(p));
    }
    for &f in &dup.copies.faces {
        // Also refreshes the stored normal from the reflected positions.
        mesh.reverse_face(f)?;
    }

    // Seam candidates: the pairs whose original (and so its copy) lies
    // within merge_distance of the plane. Two points on opposite sides of
    // the plane are at least as far apart as the sum of their distances to
    // it, so no other copy–original pair across it can be that close.
    let mut candidates: Vec<VertId> = Vec::new();
    for &(original, copy) in &dup.vert_pairs {
        if signed(mesh.position(original)).abs() <= merge_distance {
            candidates.push(original);
            candidates.push(copy);
        }
    }
    let candidates = canonical(&candidates);
    let roots = cluster_roots(
        &VertPoints {
            mesh,
            verts: &candidates,
        },
        merge_distance,
    );
    let is_copy = |v: VertId| dup.copies.verts.binary_search(&v).is_ok();
    // Per cluster, keep an original if there is one (lowest id first).
    let rank = |i: usize| (is_copy(candidates[i]), i);
    let mut best: Vec<u32> = (0..candidates.len() as u32).collect();
    for (i, &root) in roots.iter().enumerate() {
        let r = root as usize;
        if rank(i) < rank(best[r] as usize) {
            best[r] = i as u32;
        }
    }
    let targets: Vec<u32> = roots.iter().map(|&r| best[r as usize]).collect();
    weld(mesh, &candidates, &targets)?;

    let copies = dup.copies;
    Ok(Selection {
        verts: copies
            .verts
            .into_iter()
            .filter(|&v| mesh.contains_vert(v))
            .collect(),
        edges: copies
            .edges
            .into_iter()
            .filter(|&e| mesh.contains_edge(e))
            .collect(),
        faces: copies
            .faces
            .into_iter()
            .filter(|&f| mesh.contains_face(f))
            .collect(),
    })
}

fn check_distance(name: &'static str, distance: f64) -> Result<(), OpError> {
    if !distance.is_finite() || distance < 0.0 {
        return Err(OpError::parameter(
            name,
            format!("must be finite and not negative, got {distance}"),
        ));
    }
    Ok(())
}

mod cluster;
#[cfg(test)]
mod tests;
mod weld;

#[cfg(test)]
use cluster::*;
pub(in crate::kernel::ops) use cluster::{cell_coordinate, cluster_roots, VertPoints};
pub(in crate::kernel::ops) use weld::weld_gone;
use weld::*;
