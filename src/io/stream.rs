//! The binary messages a viewer streams of the bodies' surfaces: their triangles when
//! a topology changes, their vertex positions every frame. Every field is a 4-byte
//! little-endian word, so a page reads a message as typed arrays without copying.
//!
//! ```text
//! topology:  [1, bodies, { version, vertices, triangles, indices[3·t], pieces[t] }…]
//! positions: [2, frame, bodies, { version, vertices, xyz[3·v] (f32) }…]
//! ```
//! A body's `version` is its [`topology_version`](crate::ecs::surface_mesh::SurfaceMesh::topology_version)
//! (low 32 bits): positions whose versions differ from the topology a page holds wait
//! for the next topology message.

use crate::error::{CleaveError, Result};
use glam::Vec3;

/// First word of a topology message.
pub const TOPOLOGY: u32 = 1;
/// First word of a positions message.
pub const POSITIONS: u32 = 2;

/// One body's surface, as the messages carry it.
#[derive(Clone, Copy, Debug)]
pub struct StreamedSurface<'a> {
    /// Topology version (low 32 bits are sent).
    pub version: u64,
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Triangles, as vertex indices.
    pub triangles: &'a [[u32; 3]],
    /// Piece of each triangle.
    pub pieces: &'a [u32],
}

/// The topology message of `surfaces`.
pub fn encode_topology(surfaces: &[StreamedSurface]) -> Vec<u8> {
    let words: usize = surfaces.iter().map(|s| 3 + 4 * s.triangles.len()).sum();
    let mut out = Words(Vec::with_capacity(4 * (2 + words)));
    out.u32(TOPOLOGY);
    out.u32(surfaces.len() as u32);
    for s in surfaces {
        out.u32(s.version as u32);
        out.u32(s.positions.len() as u32);
        out.u32(s.triangles.len() as u32);
        for &index in s.triangles.iter().flatten() {
            out.u32(index);
        }
        for &piece in s.pieces {
            out.u32(piece);
        }
    }
    out.0
}

/// The positions message of `surfaces` at frame `frame`.
pub fn encode_positions(frame: u64, surfaces: &[StreamedSurface]) -> Vec<u8> {
    let words: usize = surfaces.iter().map(|s| 2 + 3 * s.positions.len()).sum();
    let mut out = Words(Vec::with_capacity(4 * (3 + words)));
    out.u32(POSITIONS);
    out.u32(frame as u32);
    out.u32(surfaces.len() as u32);
    for s in surfaces {
        out.u32(s.version as u32);
        out.u32(s.positions.len() as u32);
        for &x in s.positions {
            for c in x.to_array() {
                out.0.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    out.0
}

/// One body's part of a decoded topology message.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyTopology {
    /// Topology version (low 32 bits).
    pub version: u32,
    /// Vertex count.
    pub vertices: u32,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Piece of each triangle.
    pub pieces: Vec<u32>,
}

/// A decoded message (what a page reads; for checks and tools).
#[derive(Clone, Debug, PartialEq)]
pub enum Decoded {
    /// Per body, its topology.
    Topology(Vec<BodyTopology>),
    /// The frame, and per body: version, positions.
    Positions(u32, Vec<(u32, Vec<Vec3>)>),
}

/// Reads a message back; an error for a truncated or unknown one.
pub fn decode(bytes: &[u8]) -> Result<Decoded> {
    let bad = || CleaveError::InvalidEntity("a truncated or unknown stream message".into());
    if !bytes.len().is_multiple_of(4) {
        return Err(bad());
    }
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        .collect();
    let mut at = 0usize;
    let mut next = |n: usize| -> Result<&[u32]> {
        let slice = words.get(at..at + n).ok_or_else(bad)?;
        at += n;
        Ok(slice)
    };
    let decoded = match next(1)?[0] {
        TOPOLOGY => {
            let bodies = next(1)?[0];
            let mut out = Vec::new();
            for _ in 0..bodies {
                let &[version, vertices, triangles] = next(3)? else {
                    return Err(bad());
                };
                let t = triangles as usize;
                let triangles = next(3 * t)?
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect();
                out.push(BodyTopology {
                    version,
                    vertices,
                    triangles,
                    pieces: next(t)?.to_vec(),
                });
            }
            Decoded::Topology(out)
        }
        POSITIONS => {
            let &[frame, bodies] = next(2)? else {
                return Err(bad());
            };
            let mut out = Vec::new();
            for _ in 0..bodies {
                let &[version, vertices] = next(2)? else {
                    return Err(bad());
                };
                let xyz = next(3 * vertices as usize)?
                    .chunks_exact(3)
                    .map(|c| {
                        Vec3::new(
                            f32::from_bits(c[0]),
                            f32::from_bits(c[1]),
                            f32::from_bits(c[2]),
                        )
                    })
                    .collect();
                out.push((version, xyz));
            }
            Decoded::Positions(frame, out)
        }
        _ => return Err(bad()),
    };
    if at != words.len() {
        return Err(bad());
    }
    Ok(decoded)
}

struct Words(Vec<u8>);

impl Words {
    fn u32(&mut self, w: u32) {
        self.0.extend_from_slice(&w.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_read_back_as_they_were_written_and_bad_ones_are_refused() {
        let positions = [Vec3::new(1.0, -2.5, 3.25), Vec3::ZERO, Vec3::ONE];
        let triangles = [[0, 1, 2], [2, 1, 0]];
        let surfaces = [
            StreamedSurface {
                version: (7 << 32) | 3,
                positions: &positions,
                triangles: &triangles,
                pieces: &[0, 1],
            },
            StreamedSurface {
                version: 1,
                positions: &[],
                triangles: &[],
                pieces: &[],
            },
        ];
        let topology = encode_topology(&surfaces);
        assert_eq!(topology.len(), 4 * (2 + 3 + 6 + 2 + 3));
        assert_eq!(
            decode(&topology).unwrap(),
            Decoded::Topology(vec![
                BodyTopology {
                    version: 3,
                    vertices: 3,
                    triangles: triangles.to_vec(),
                    pieces: vec![0, 1]
                },
                BodyTopology {
                    version: 1,
                    vertices: 0,
                    triangles: vec![],
                    pieces: vec![]
                }
            ])
        );
        let frame = encode_positions(42, &surfaces);
        assert_eq!(frame.len(), 4 * (3 + 2 + 9 + 2));
        assert_eq!(
            decode(&frame).unwrap(),
            Decoded::Positions(42, vec![(3, positions.to_vec()), (1, vec![])])
        );
        for bad in [
            &frame[..frame.len() - 4],
            &frame[..7],
            &[9, 0, 0, 0][..],
            &[],
        ] {
            assert!(decode(bad).is_err());
        }
    }
}
