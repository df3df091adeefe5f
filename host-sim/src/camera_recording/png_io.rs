//! 8-bit grayscale PNG frames through the `png` crate: decoding refuses
//! anything else (colour, 16 bits, a wrong size, a truncated stream) with
//! the file's name.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use super::error::RecordingError;

/// Reads an 8-bit grayscale PNG of `width` x `height`, rows top to bottom.
pub fn read_gray_png(
    path: &Path,
    name: &str,
    width: u32,
    height: u32,
) -> Result<Vec<u8>, RecordingError> {
    let file =
        File::open(path).map_err(|e| RecordingError::image(name, format!("cannot open: {e}")))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder
        .read_info()
        .map_err(|e| RecordingError::image(name, format!("not a readable PNG: {e}")))?;
    let info = reader.info();
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Eight {
        return Err(RecordingError::image(
            name,
            format!(
                "must be 8-bit grayscale, is {:?} at {:?} bits",
                info.color_type, info.bit_depth
            ),
        ));
    }
    if (info.width, info.height) != (width, height) {
        return Err(RecordingError::image(
            name,
            format!(
                "is {} x {}, the header says {width} x {height}",
                info.width, info.height
            ),
        ));
    }
    let mut pixels = vec![0u8; reader.output_buffer_size()];
    let frame = reader
        .next_frame(&mut pixels)
        .map_err(|e| RecordingError::image(name, format!("cannot decode: {e}")))?;
    pixels.truncate(frame.buffer_size());
    let expected = width as usize * height as usize;
    if frame.line_size != width as usize || pixels.len() != expected {
        return Err(RecordingError::image(name, "unexpected row layout"));
    }
    Ok(pixels)
}

/// Writes `pixels` (rows top to bottom) as an 8-bit grayscale PNG.
pub fn write_gray_png(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[u8],
) -> Result<(), RecordingError> {
    let file = File::create(path).map_err(RecordingError::io(path))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Best);
    let name = path.display().to_string();
    let mut writer = encoder
        .write_header()
        .map_err(|e| RecordingError::image(&name, format!("cannot encode: {e}")))?;
    writer
        .write_image_data(pixels)
        .map_err(|e| RecordingError::image(&name, format!("cannot encode: {e}")))?;
    writer
        .finish()
        .map_err(|e| RecordingError::image(&name, format!("cannot encode: {e}")))
}
