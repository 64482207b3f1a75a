//! A JPEG's structure, checked before it is decoded: the JPEG decoder fills what a file does not
//! hold with zeros (a file cut at 80 % was read without a word) and allocates the size its
//! header declares whatever the data (a 4,000-byte file declaring 16000×16000 took 4.5 GB and
//! 18 s). So the markers are walked from the start of the image to its end marker (a file that
//! ends before it is truncated), and the entropy-coded data must hold at least one bit for each
//! 8×8 block of the first component (every block is coded in some scan with at least one
//! Huffman code of at least one bit), which bounds the pixels by the file's size.

/// Why the JPEG `b` cannot be a whole image; `Ok` when its structure holds.
pub(crate) fn check(b: &[u8]) -> Result<(), String> {
    if !b.starts_with(&[0xFF, 0xD8]) {
        return Err("no JPEG start-of-image marker".into());
    }
    let truncated = |what: &str| format!("truncated: the file ends {what}, before its end marker");
    let mut at = 2usize;
    let mut blocks: Option<u64> = None;
    let mut data_bits = 0u64;
    loop {
        // A marker, after any fill bytes.
        if b.get(at) != Some(&0xFF) {
            return Err(match b.get(at) {
                None => truncated("between two segments"),
                Some(_) => format!("no marker at byte {at}"),
            });
        }
        while b.get(at + 1) == Some(&0xFF) {
            at += 1;
        }
        let Some(&m) = b.get(at + 1) else {
            return Err(truncated("inside a marker"));
        };
        at += 2;
        match m {
            0xD9 => break,
            0x01 | 0xD0..=0xD7 => continue,
            _ => {}
        }
        let len = b
            .get(at..at + 2)
            .map(|l| usize::from(u16::from_be_bytes([l[0], l[1]])))
            .ok_or_else(|| truncated("inside a segment's length"))?;
        if len < 2 {
            return Err(format!("a segment of length {len} at byte {at}"));
        }
        let seg = b
            .get(at + 2..at + len)
            .ok_or_else(|| truncated("inside a segment"))?;
        if matches!(m, 0xC0..=0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF) {
            let [_, h0, h1, w0, w1, ..] = seg else {
                return Err("a short frame header".into());
            };
            let (h, w) = (
                u64::from(u16::from_be_bytes([*h0, *h1])),
                u64::from(u16::from_be_bytes([*w0, *w1])),
            );
            blocks = Some(w.div_ceil(8) * h.div_ceil(8));
        }
        at += len;
        if m == 0xDA {
            let start = at;
            at = entropy_end(b, at).ok_or_else(|| truncated("inside its image data"))?;
            data_bits += 8 * (at - start) as u64;
        }
    }
    let blocks = blocks.ok_or("no frame header")?;
    if data_bits < blocks {
        return Err(format!(
            "{} bytes of image data cannot hold its {blocks} blocks of 8×8 pixels (one bit each at least)",
            data_bits / 8
        ));
    }
    Ok(())
}

/// Where the entropy-coded data starting at `at` ends: the next marker other than a stuffed
/// byte or a restart marker; `None` when the file ends first.
fn entropy_end(b: &[u8], mut at: usize) -> Option<usize> {
    loop {
        let ff = at + b.get(at..)?.iter().position(|&x| x == 0xFF)?;
        match b.get(ff + 1)? {
            0x00 | 0xD0..=0xD7 => at = ff + 2,
            // Fill bytes before a marker.
            0xFF => at = ff + 1,
            _ => return Some(ff),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg(w: u32, h: u32) -> Vec<u8> {
        let mut img = image::RgbImage::new(w, h);
        for (x, y, p) in img.enumerate_pixels_mut() {
            *p = image::Rgb([(x * 7) as u8, (y * 3) as u8, ((x + y) * 5) as u8]);
        }
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
            .encode_image(&img)
            .unwrap();
        out
    }

    #[test]
    fn a_whole_jpeg_holds_and_a_cut_one_does_not() {
        let b = jpeg(64, 48);
        assert_eq!(check(&b), Ok(()));
        for keep in [b.len() * 8 / 10, b.len() - 2, 20, 3] {
            let e = check(&b[..keep]).unwrap_err();
            assert!(e.contains("truncated"), "{keep}: {e}");
        }
    }

    #[test]
    fn a_header_larger_than_its_data_is_refused() {
        let mut b = jpeg(64, 48);
        let sof = b.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
        b[sof + 5..sof + 9].copy_from_slice(&[0x3E, 0x80, 0x3E, 0x80]);
        let e = check(&b).unwrap_err();
        assert!(e.contains("4000000 blocks"), "{e}");
    }
}
