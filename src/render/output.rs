//! Render outputs: linear f32 RGBA OpenEXR, a tone-mapped sRGB PNG and a JSON sidecar, each
//! encoded in memory and written atomically (`io::write_atomic`).

use std::io::Cursor;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::error::{Error, Result};
use crate::scene::Mesh;

/// OpenEXR bytes: linear f32 R, G, B (mean radiance) and A (primary-ray coverage), row 0 at
/// the top.
pub fn encode_exr(width: u32, height: u32, rgba: &[[f32; 4]]) -> Result<Vec<u8>> {
    use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage};
    let w = width as usize;
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let p: [f32; 4] = rgba[y * w + x];
        (p[0], p[1], p[2], p[3])
    });
    let image = Image::from_channels((w, height as usize), channels);
    let mut bytes = Cursor::new(Vec::new());
    image.write().to_buffered(&mut bytes).map_err(|e| Error::Usage(format!("encoding OpenEXR: {e}")))?;
    Ok(bytes.into_inner())
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// 8-bit sRGB PNG bytes: radiance scaled by 2^exposure, clipped to [0, 1], sRGB-encoded.
/// (Clipping, not a curve: the default white environment then shows as white.)
pub fn encode_png(width: u32, height: u32, rgba: &[[f32; 4]], exposure: f32) -> Result<Vec<u8>> {
    let scale = exposure.exp2();
    let mut pixels = Vec::with_capacity(rgba.len() * 3);
    for p in rgba {
        for c in &p[..3] {
            let v = if c.is_finite() { (c * scale).clamp(0.0, 1.0) } else { 0.0 };
            pixels.push((srgb_encode(v) * 255.0 + 0.5) as u8);
        }
    }
    let mut bytes = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
    image::ImageEncoder::write_image(encoder, &pixels, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::Usage(format!("encoding PNG: {e}")))?;
    Ok(bytes)
}

/// SHA-256 of what the render reads from the scene: vertex positions, triangles, material
/// indices and the material records, so two scenes with the same hash render the same
/// (whatever their OBJ formatting).
pub fn scene_hash(mesh: &Mesh) -> String {
    let mut h = Sha256::new();
    h.update(bytemuck::cast_slice(&mesh.positions));
    h.update(bytemuck::cast_slice(&mesh.triangles));
    h.update(bytemuck::cast_slice(&mesh.material_ids));
    for m in &mesh.materials {
        h.update(bytemuck::bytes_of(&m.gpu));
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// `image.exr` -> (`image.png`, `image.json`).
pub fn sidecar_paths(exr: &Path) -> (PathBuf, PathBuf) {
    (exr.with_extension("png"), exr.with_extension("json"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_matches_the_standard_at_known_points() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        // 18 % grey encodes to 0.4613 (IEC 61966-2-1).
        assert!((srgb_encode(0.18) - 0.4613).abs() < 1e-3);
        // Continuous at the knee.
        assert!((srgb_encode(0.003_130_8) - srgb_encode(0.003_130_9)).abs() < 1e-5);
    }

    #[test]
    fn exr_round_trips_f32_exactly() {
        let px: Vec<[f32; 4]> = (0..6).map(|i| [i as f32 * 0.1, 1.5e-8, 3.0e5, (i % 2) as f32]).collect();
        let bytes = encode_exr(3, 2, &px).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        std::fs::write(&path, &bytes).unwrap();
        let img = exr::prelude::read_first_rgba_layer_from_file(
            &path,
            |res, _| vec![[0f32; 4]; res.width() * res.height()],
            |px: &mut Vec<[f32; 4]>, pos, (r, g, b, a): (f32, f32, f32, f32)| px[pos.y() * 3 + pos.x()] = [r, g, b, a],
        )
        .unwrap();
        assert_eq!(img.layer_data.size.width(), 3);
        assert_eq!(img.layer_data.channel_data.pixels, px);
    }

    #[test]
    fn png_clips_and_encodes() {
        let px = vec![[0.0, 0.18, 4.0, 1.0], [f32::NAN, 1.0, 0.5, 1.0]];
        let bytes = encode_png(2, 1, &px, 0.0).unwrap();
        let img = image::load_from_memory(&bytes).unwrap().to_rgb8();
        assert_eq!(img.get_pixel(0, 0).0, [0, 118, 255]);
        assert_eq!(img.get_pixel(1, 0).0, [0, 255, 188]);
    }
}
