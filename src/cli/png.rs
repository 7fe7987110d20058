//! The program's one PNG encoder (8-bit RGB). It lives with the commands so
//! that the library does not depend on `png`; the library hands out pixels
//! (`render::Image::to_rgb8`, `render::difference_rgb8`).

/// Encode 8-bit RGB pixels (`width * height * 3` bytes, rows top to bottom)
/// as a PNG file's bytes.
pub fn encode_png(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| e.to_string())?;
        w.write_image_data(rgb).map_err(|e| e.to_string())?;
    }
    Ok(out)
}
