//! Binary glTF 2.0 export of the surfaces: one `.glb` file per picture frame, a mesh
//! (and a node) per piece, positions, normals and `u32` triangle indices, readable by
//! Blender (File → Import → glTF 2.0) and every glTF viewer.
//!
//! The pieces of one body share that body's vertex arrays; each has its own indices.

use crate::io::render::surfaces::SurfaceToDraw;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::Path;

/// glTF's component type of a 32-bit float and of a 32-bit unsigned integer.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
/// glTF's buffer-view targets: vertex attributes, and indices.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// Writes the surfaces as one binary glTF file.
pub fn write_glb(path: &Path, surfaces: &[SurfaceToDraw]) -> Result<(), String> {
    let fail = |e: std::io::Error| format!("cannot write `{}`: {e}", path.display());
    let (json, bin) = gltf_parts(surfaces);
    std::fs::write(path, glb(&json, &bin)).map_err(fail)
}

/// The glTF JSON and its binary buffer.
fn gltf_parts(surfaces: &[SurfaceToDraw]) -> (Value, Vec<u8>) {
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors) = (Vec::new(), Vec::new());
    let mut view = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| {
        views.push(json!({
            "buffer": 0,
            "byteOffset": bin.len(),
            "byteLength": bytes.len(),
            "target": target,
        }));
        bin.extend_from_slice(bytes);
        views.len() - 1
    };
    let mut meshes: BTreeMap<u32, Vec<Value>> = BTreeMap::new();
    for s in surfaces.iter().filter(|s| !s.positions.is_empty()) {
        let floats = |v: &[glam::Vec3]| -> Vec<u8> {
            v.iter()
                .flat_map(|p| p.to_array())
                .flat_map(f32::to_le_bytes)
                .collect()
        };
        let (lo, hi) = s
            .positions
            .iter()
            .fold((glam::Vec3::MAX, glam::Vec3::MIN), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
        let at = view(&mut bin, &floats(&s.positions), ARRAY_BUFFER);
        accessors.push(json!({
            "bufferView": at, "componentType": FLOAT, "count": s.positions.len(),
            "type": "VEC3", "min": lo.to_array(), "max": hi.to_array(),
        }));
        let positions = accessors.len() - 1;
        let at = view(&mut bin, &floats(&s.normals), ARRAY_BUFFER);
        accessors.push(json!({
            "bufferView": at, "componentType": FLOAT, "count": s.normals.len(), "type": "VEC3",
        }));
        let normals = accessors.len() - 1;
        let mut by_piece: BTreeMap<u32, Vec<u8>> = BTreeMap::new();
        for (t, piece) in s.triangles.iter().zip(&s.pieces) {
            by_piece
                .entry(*piece)
                .or_default()
                .extend(t.iter().flat_map(|v| v.to_le_bytes()));
        }
        for (piece, indices) in by_piece {
            let at = view(&mut bin, &indices, ELEMENT_ARRAY_BUFFER);
            accessors.push(json!({
                "bufferView": at, "componentType": UNSIGNED_INT, "count": indices.len() / 4,
                "type": "SCALAR",
            }));
            meshes.entry(piece).or_default().push(json!({
                "attributes": { "POSITION": positions, "NORMAL": normals },
                "indices": accessors.len() - 1,
            }));
        }
    }
    let (mut mesh_list, mut nodes) = (Vec::new(), Vec::new());
    for (piece, primitives) in meshes {
        nodes.push(json!({ "mesh": mesh_list.len(), "name": format!("piece_{piece}") }));
        mesh_list.push(json!({ "name": format!("piece_{piece}"), "primitives": primitives }));
    }
    let mut gltf = json!({
        "asset": { "version": "2.0", "generator": "cleave" },
        "scene": 0,
        "scenes": [{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": mesh_list,
        "accessors": accessors,
        "bufferViews": views,
    });
    if !bin.is_empty() {
        gltf["buffers"] = json!([{ "byteLength": bin.len() }]);
    }
    (gltf, bin)
}

/// The GLB container: a 12-byte header, the JSON chunk padded with spaces and the
/// binary chunk padded with zeros, each to four bytes.
fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut text = json.to_string().into_bytes();
    text.resize(text.len().next_multiple_of(4), b' ');
    let mut data = bin.to_vec();
    data.resize(data.len().next_multiple_of(4), 0);
    let bin_chunk = if data.is_empty() { 0 } else { 8 + data.len() };
    let total = 12 + 8 + text.len() + bin_chunk;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    if !data.is_empty() {
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&data);
    }
    out
}
