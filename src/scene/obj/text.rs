//! Reading an OBJ or MTL file as text (module docs, step 1): the encodings, and a reader
//! that knows which line `tobj` stopped on.

use std::io::{BufRead, Read};

/// Decodes a text file: UTF-16 (LE or BE) when it starts with a byte-order mark, otherwise
/// UTF-8 with an optional BOM and invalid sequences replaced. A file using lone `\r` line
/// ends (and no `\n`) gets `\n` ones.
pub(super) fn decode_text(mut bytes: Vec<u8>) -> String {
    let utf16 = |big_endian: bool, body: &[u8]| {
        let units = body.chunks_exact(2).map(|c| match *c {
            [a, b] if big_endian => u16::from_be_bytes([a, b]),
            [a, b] => u16::from_le_bytes([a, b]),
            _ => 0xFFFD,
        });
        char::decode_utf16(units).map(|c| c.unwrap_or(char::REPLACEMENT_CHARACTER)).collect::<String>()
    };
    let utf8 = |bytes: Vec<u8>| {
        // Valid UTF-8 (the usual case) is used in place, without a copy.
        String::from_utf8(bytes).unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned())
    };
    let text = match bytes[..] {
        [0xFE, 0xFF, ..] => utf16(true, bytes.get(2..).unwrap_or_default()),
        [0xFF, 0xFE, ..] => utf16(false, bytes.get(2..).unwrap_or_default()),
        [0xEF, 0xBB, 0xBF, ..] => {
            bytes.drain(..3);
            utf8(bytes)
        }
        _ => utf8(bytes),
    };
    if text.contains('\r') && !text.contains('\n') {
        text.replace('\r', "\n")
    } else {
        text
    }
}

/// A `BufRead` over the pre-pass text that knows which line `tobj` read last.
pub(super) struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
    newlines: usize,
    ends_with_newline: bool,
}

impl<'a> LineCounter<'a> {
    pub(super) fn new(data: &'a [u8]) -> Self {
        LineCounter { data, pos: 0, newlines: 0, ends_with_newline: false }
    }

    /// 1-based number of the line most recently consumed (1 before any reading).
    pub(super) fn line(&self) -> usize {
        if self.ends_with_newline {
            self.newlines
        } else {
            self.newlines + 1
        }
    }
}

impl Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let avail = self.fill_buf()?;
        let n = avail.len().min(buf.len());
        if let (Some(dst), Some(src)) = (buf.get_mut(..n), avail.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(self.data.get(self.pos..).unwrap_or_default())
    }

    fn consume(&mut self, amt: usize) {
        let end = self.pos.saturating_add(amt).min(self.data.len());
        let chunk = self.data.get(self.pos..end).unwrap_or_default();
        self.newlines += chunk.iter().filter(|&&b| b == b'\n').count();
        if let Some(&last) = chunk.last() {
            self.ends_with_newline = last == b'\n';
        }
        self.pos = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_counter_tracks_lines() {
        let mut r = LineCounter::new(b"a\nbb\n\nc");
        assert_eq!(r.line(), 1);
        let mut lines = Vec::new();
        let mut s = String::new();
        while r.read_line(&mut s).unwrap() > 0 {
            lines.push(r.line());
            s.clear();
        }
        assert_eq!(lines, [1, 2, 3, 4]);
    }

    #[test]
    fn decodes_boms_and_utf16() {
        let d = |b: &[u8]| decode_text(b.to_vec());
        assert_eq!(d(b"\xEF\xBB\xBFv 1"), "v 1");
        assert_eq!(d(b"\xFE\xFF\0v\0 \x001"), "v 1");
        assert_eq!(d(b"\xFF\xFEv\0 \x001\0"), "v 1");
        assert_eq!(d(b"a\rb"), "a\nb");
        assert_eq!(d(b"a\xFFb"), "a\u{FFFD}b");
    }
}
