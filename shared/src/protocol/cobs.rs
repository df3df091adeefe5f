//! Consistent Overhead Byte Stuffing: removes every 0x00 from a frame body so
//! that 0x00 can delimit frames and a receiver can resynchronise on it after
//! garbage.

/// Worst-case encoded length of `raw_len` bytes (one overhead byte per 254).
pub const fn max_encoded_len(raw_len: usize) -> usize {
    raw_len + raw_len / 254 + 1
}

/// Why a COBS body could not be encoded or decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CobsError {
    /// The output buffer is too small.
    OutputFull,
    /// A code byte was 0 or pointed past the end of the body.
    Malformed,
}

impl core::fmt::Display for CobsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::OutputFull => f.write_str("COBS: the output buffer is too small for the body"),
            Self::Malformed => {
                f.write_str("COBS: a code byte is 0 or points past the end of the body")
            }
        }
    }
}

impl core::error::Error for CobsError {}

/// Encodes `raw` into `out` (no delimiter); returns the encoded length.
pub fn encode(raw: &[u8], out: &mut [u8]) -> Result<usize, CobsError> {
    let mut code_at = 0usize;
    let mut written = 1usize;
    let mut code: u8 = 1;
    for &byte in raw {
        if byte == 0 {
            put(out, code_at, code)?;
            code_at = written;
            written += 1;
            code = 1;
        } else {
            put(out, written, byte)?;
            written += 1;
            code += 1;
            if code == 0xFF {
                put(out, code_at, code)?;
                code_at = written;
                written += 1;
                code = 1;
            }
        }
    }
    put(out, code_at, code)?;
    Ok(written)
}

/// Decodes the body `encoded` (no delimiter) into `out`; returns the decoded length.
pub fn decode(encoded: &[u8], out: &mut [u8]) -> Result<usize, CobsError> {
    let mut read = 0usize;
    let mut written = 0usize;
    while let Some(&code) = encoded.get(read) {
        if code == 0 {
            return Err(CobsError::Malformed);
        }
        read += 1;
        let run = usize::from(code) - 1;
        let chunk = encoded.get(read..read + run).ok_or(CobsError::Malformed)?;
        if chunk.contains(&0) {
            return Err(CobsError::Malformed);
        }
        out.get_mut(written..written + run)
            .ok_or(CobsError::OutputFull)?
            .copy_from_slice(chunk);
        written += run;
        read += run;
        // A code below 0xFF stands for a zero after its run, except at the very end.
        if code < 0xFF && read < encoded.len() {
            put(out, written, 0)?;
            written += 1;
        }
    }
    Ok(written)
}

fn put(out: &mut [u8], at: usize, byte: u8) -> Result<(), CobsError> {
    *out.get_mut(at).ok_or(CobsError::OutputFull)? = byte;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(raw: &[u8]) {
        let mut enc = [0u8; 1024];
        let n = encode(raw, &mut enc).unwrap();
        assert!(n <= max_encoded_len(raw.len()));
        assert!(!enc[..n].contains(&0), "encoded body holds a zero");
        let mut dec = [0u8; 1024];
        let m = decode(&enc[..n], &mut dec).unwrap();
        assert_eq!(&dec[..m], raw);
    }

    #[test]
    fn known_vectors() {
        let mut enc = [0u8; 16];
        let n = encode(&[0x11, 0x22, 0x00, 0x33], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        let n = encode(&[0x00], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x01, 0x01]);
        let n = encode(&[], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x01]);
    }

    #[test]
    fn round_trips_including_long_runs() {
        round_trip(&[]);
        round_trip(&[0, 0, 0]);
        let long: [u8; 600] = core::array::from_fn(|i| (i % 255) as u8 + 1);
        round_trip(&long);
        let mixed: [u8; 600] = core::array::from_fn(|i| (i % 7) as u8);
        round_trip(&mixed);
        let exact: [u8; 254] = [7; 254];
        round_trip(&exact);
    }

    #[test]
    fn rejects_malformed() {
        let mut out = [0u8; 16];
        assert_eq!(decode(&[0x05, 0x11], &mut out), Err(CobsError::Malformed));
        assert_eq!(decode(&[0x00], &mut out), Err(CobsError::Malformed));
        assert_eq!(
            decode(&[0x03, 0x11, 0x00], &mut out),
            Err(CobsError::Malformed)
        );
        let mut tiny = [0u8; 1];
        assert_eq!(
            decode(&[0x03, 0x11, 0x22], &mut tiny),
            Err(CobsError::OutputFull)
        );
    }
}
