//! Synthetic scenes of any size, for scale tests and benchmarks: `synth:<kind>:<triangles>[:<seed>]`
//! wherever a scene path is accepted (`synth:terrain:10M`, `synth:soup:2500k:7`).
//!
//! Kinds (all inside the unit cube, deterministic for a given spec, generated in parallel):
//! - `terrain`: a height field over a square grid, two triangles per cell, heights from a sum
//!   of sines plus per-vertex noise. Shared vertices, little overlap: a well-behaved big mesh,
//!   like a scan.
//! - `soup`: independent random triangles (three vertices each), edge length about twice the
//!   mean spacing (at most 0.25), so boxes overlap heavily: a hard case for any BVH builder.
//! - `spheres`: a grid of closed UV spheres (latitude-longitude tessellation) of about 2,000
//!   triangles each: many separate objects with empty space between them.
//!
//! The triangle count is exact: the mesh is generated with at least that many and truncated.

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;

use super::{Material, Mesh};
use crate::error::{Error, Result};

/// The prefix that marks a synthetic scene spec.
pub const PREFIX: &str = "synth:";

/// Most triangles a synthetic scene may ask for (vertex and triangle ids are u32).
pub const MAX_TRIANGLES: u64 = 1 << 30;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Terrain,
    Soup,
    Spheres,
}

/// A parsed `synth:` spec.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Spec {
    pub kind: Kind,
    pub triangles: u64,
    pub seed: u64,
}

/// True when `path` is a `synth:` spec rather than a file.
pub fn is_spec(path: &Path) -> bool {
    path.to_str().is_some_and(|s| s.starts_with(PREFIX))
}

impl Spec {
    /// Parses `synth:<kind>:<count>[:<seed>]`; the count takes a `k` (10^3) or `M` (10^6) suffix.
    pub fn parse(path: &Path) -> Result<Spec> {
        let bad = |m: String| Error::bad_input(path, None, m);
        let s = path.to_str().ok_or_else(|| bad("not UTF-8".into()))?;
        let rest = s.strip_prefix(PREFIX).ok_or_else(|| bad(format!("a synthetic scene starts with `{PREFIX}`")))?;
        let parts: Vec<&str> = rest.split(':').collect();
        if !(2..=3).contains(&parts.len()) {
            return Err(bad(
                "expected synth:<terrain|soup|spheres>:<triangles>[:<seed>], e.g. synth:terrain:10M".into()
            ));
        }
        let kind = match parts[0] {
            "terrain" => Kind::Terrain,
            "soup" => Kind::Soup,
            "spheres" => Kind::Spheres,
            k => return Err(bad(format!("unknown synthetic scene kind `{k}` (terrain, soup or spheres)"))),
        };
        let triangles = parse_count(parts[1]).ok_or_else(|| {
            bad(format!("triangle count `{}` is not a number (suffixes k and M allowed: 10M, 2500k)", parts[1]))
        })?;
        if triangles == 0 || triangles > MAX_TRIANGLES {
            return Err(bad(format!("triangle count {triangles} is outside 1..={MAX_TRIANGLES}")));
        }
        let seed = match parts.get(2) {
            Some(s) => s.parse().map_err(|_| bad(format!("seed `{s}` is not an unsigned integer")))?,
            None => 1,
        };
        Ok(Spec { kind, triangles, seed })
    }
}

fn parse_count(s: &str) -> Option<u64> {
    let (digits, mult) = match s.as_bytes().last()? {
        b'k' | b'K' => (&s[..s.len() - 1], 1_000),
        b'M' | b'm' => (&s[..s.len() - 1], 1_000_000),
        _ => (s, 1),
    };
    digits.parse::<u64>().ok()?.checked_mul(mult)
}

/// Generates the scene a `synth:` spec names.
pub fn load(path: &Path) -> Result<Mesh> {
    let spec = Spec::parse(path)?;
    // Each triangle's indices and material id (16 bytes), and its share of the vertices: three
    // of its own in a soup, about half of one in a grid or a sphere.
    let each = match spec.kind {
        Kind::Soup => 16 + 3 * 12,
        Kind::Terrain | Kind::Spheres => 16 + 6,
    };
    let need = crate::memory::Need::new(path.display().to_string(), "triangles", Some(spec.triangles), each);
    crate::memory::check(&[need])?;
    let n = spec.triangles as usize;
    let (positions, mut triangles) = match spec.kind {
        Kind::Terrain => terrain(n, spec.seed),
        Kind::Soup => soup(n, spec.seed),
        Kind::Spheres => spheres(n),
    };
    triangles.truncate(n);
    debug_assert_eq!(triangles.len(), n);
    Ok(Mesh {
        source: PathBuf::from(path),
        positions,
        material_ids: vec![0; triangles.len()],
        triangles,
        materials: vec![Material::default()],
        mtl_files: vec![],
        warnings: vec![],
    })
}

/// Rows of `cells x cells` grid cells, two triangles each.
fn terrain(n: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let cells = (n.div_ceil(2) as f64).sqrt().ceil() as usize;
    let side = cells + 1;
    let phase = (seed % 1000) as f32 * 0.001;
    let positions: Vec<[f32; 3]> = (0..side * side)
        .into_par_iter()
        .map(|i| {
            let (x, z) = ((i % side) as f32 / cells as f32, (i / side) as f32 / cells as f32);
            // Deterministic per-vertex jitter from a hash of (seed, vertex), no shared RNG state.
            let h = hash(seed, i as u64);
            let jitter = (h >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
            let y = 0.1 * ((7.0 * x + phase).sin() * (5.0 * z).cos())
                + 0.03 * (23.0 * x * z + phase).sin()
                + jitter * 0.25 / cells as f32;
            [x, 0.5 + y, z]
        })
        .collect();
    let rows = n.div_ceil(2).div_ceil(cells);
    let triangles: Vec<[u32; 3]> = (0..rows * cells)
        .into_par_iter()
        .flat_map_iter(|c| {
            let (cx, cz) = ((c % cells) as u32, (c / cells) as u32);
            let v = |x: u32, z: u32| z * side as u32 + x;
            let (a, b, cc, d) = (v(cx, cz), v(cx + 1, cz), v(cx + 1, cz + 1), v(cx, cz + 1));
            [[a, cc, b], [a, d, cc]]
        })
        .collect();
    (positions, triangles)
}

/// `n` independent triangles with random centres in the unit cube.
fn soup(n: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    // Mean spacing of n points in the unit cube is n^(-1/3); edges of about twice that.
    let size = (2.0 * (n as f64).powf(-1.0 / 3.0)).min(0.25);
    const CHUNK: usize = 1 << 16;
    let positions: Vec<[f32; 3]> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .flat_map_iter(|chunk| {
            // One generator per chunk, seeded by (seed, chunk): the output does not depend on
            // how rayon schedules the chunks.
            let mut rng = Pcg32::seed_from_u64(hash(seed, chunk as u64));
            let count = CHUNK.min(n - chunk * CHUNK);
            let mut out = Vec::with_capacity(3 * count);
            for _ in 0..count {
                let c: [f64; 3] = [rng.random(), rng.random(), rng.random()];
                for _ in 0..3 {
                    let p = [0, 1, 2].map(|k| {
                        let d: f64 = rng.random::<f64>() - 0.5;
                        (c[k] * (1.0 - size) + size * 0.5 + d * size) as f32
                    });
                    out.push(p);
                }
            }
            out
        })
        .collect();
    let triangles = (0..n as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    (positions, triangles)
}

/// Stacks and slices of each UV sphere: 2 * SLICES * (STACKS - 1) = 1,984 triangles.
const STACKS: u32 = 32;
const SLICES: u32 = 32;

/// A `k x k x k` grid of closed UV spheres, enough for `n` triangles.
fn spheres(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let per_sphere = (2 * SLICES * (STACKS - 1)) as usize;
    let verts_per_sphere = (SLICES * (STACKS - 1) + 2) as usize;
    let count = n.div_ceil(per_sphere);
    let k = (count as f64).cbrt().ceil() as usize;
    let radius = 0.4 / k as f32;
    let positions: Vec<[f32; 3]> = (0..count)
        .into_par_iter()
        .flat_map_iter(|s| {
            let centre = [s % k, (s / k) % k, s / (k * k)].map(|c| (c as f32 + 0.5) / k as f32);
            let mut out = Vec::with_capacity(verts_per_sphere);
            out.push([centre[0], centre[1] + radius, centre[2]]);
            for i in 1..STACKS {
                let theta = std::f32::consts::PI * i as f32 / STACKS as f32;
                for j in 0..SLICES {
                    let phi = std::f32::consts::TAU * j as f32 / SLICES as f32;
                    let (st, ct) = theta.sin_cos();
                    let (sp, cp) = phi.sin_cos();
                    out.push([centre[0] + radius * st * cp, centre[1] + radius * ct, centre[2] + radius * st * sp]);
                }
            }
            out.push([centre[0], centre[1] - radius, centre[2]]);
            out
        })
        .collect();
    let triangles: Vec<[u32; 3]> = (0..count)
        .into_par_iter()
        .flat_map_iter(|s| {
            let base = (s * verts_per_sphere) as u32;
            let ring = |i: u32, j: u32| base + 1 + (i - 1) * SLICES + j % SLICES;
            let (top, bottom) = (base, base + verts_per_sphere as u32 - 1);
            let mut out = Vec::with_capacity(per_sphere);
            for j in 0..SLICES {
                out.push([top, ring(1, j + 1), ring(1, j)]);
                out.push([bottom, ring(STACKS - 1, j), ring(STACKS - 1, j + 1)]);
            }
            for i in 1..STACKS - 1 {
                for j in 0..SLICES {
                    let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
                    out.push([a, b, c]);
                    out.push([a, c, d]);
                }
            }
            out
        })
        .collect();
    (positions, triangles)
}

/// SplitMix64 of (seed, i): a stateless hash for per-element randomness.
fn hash(seed: u64, i: u64) -> u64 {
    let mut z = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ i.wrapping_add(0x632B_E59B_D9B4_E019);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(s: &str) -> Result<Spec> {
        Spec::parse(Path::new(s))
    }

    #[test]
    fn specs_parse_with_suffixes_and_reject_nonsense() {
        assert_eq!(spec("synth:terrain:10M").unwrap(), Spec { kind: Kind::Terrain, triangles: 10_000_000, seed: 1 });
        assert_eq!(spec("synth:soup:2500k:7").unwrap(), Spec { kind: Kind::Soup, triangles: 2_500_000, seed: 7 });
        assert_eq!(spec("synth:spheres:123").unwrap().triangles, 123);
        for bad in [
            "synth:cube:10",
            "synth:terrain",
            "synth:terrain:0",
            "synth:terrain:ten",
            "synth:terrain:99999999999999999999M",
            "synth:terrain:2000M",
            "synth:soup:10:x",
            "synth:soup:10:1:2",
        ] {
            let e = spec(bad).unwrap_err().to_string();
            assert!(e.starts_with(bad), "error must name the spec: {e}");
        }
    }

    #[test]
    fn each_kind_has_exactly_the_count_asked_for_and_valid_indices() {
        for kind in ["terrain", "soup", "spheres"] {
            for n in [1usize, 2, 3, 1000, 4097, 20_001] {
                let m = load(Path::new(&format!("synth:{kind}:{n}"))).unwrap();
                assert_eq!(m.triangle_count(), n, "{kind} {n}");
                assert_eq!(m.material_ids.len(), n);
                let nv = m.positions.len() as u32;
                assert!(m.triangles.iter().flatten().all(|&i| i < nv), "{kind} {n}: index out of range");
                let b = m.bounds();
                assert!(b.min.cmpge(glam::Vec3::ZERO).all() && b.max.cmple(glam::Vec3::ONE).all(), "{kind}: {b:?}");
                assert!(m.degenerate_ids().is_empty(), "{kind} {n}: degenerate triangles");
            }
        }
    }

    #[test]
    fn generation_is_deterministic_and_seeded() {
        let a = load(Path::new("synth:soup:200000:3")).unwrap();
        let b = load(Path::new("synth:soup:200000:3")).unwrap();
        let c = load(Path::new("synth:soup:200000:4")).unwrap();
        assert_eq!(a.positions, b.positions);
        assert_ne!(a.positions, c.positions);
        let t = load(Path::new("synth:terrain:50000:3")).unwrap();
        assert_eq!(t.positions, load(Path::new("synth:terrain:50000:3")).unwrap().positions);
    }

    #[test]
    fn spheres_are_closed() {
        // Every directed edge of a closed, consistently wound mesh appears once, its reverse once.
        let m = load(Path::new("synth:spheres:3968")).unwrap(); // exactly two spheres
        let mut edges = std::collections::HashSet::new();
        for t in &m.triangles {
            for k in 0..3 {
                assert!(edges.insert((t[k], t[(k + 1) % 3])), "directed edge repeated");
            }
        }
        assert!(edges.iter().all(|&(a, b)| edges.contains(&(b, a))), "an edge has no twin: the sphere has a hole");
    }
}
