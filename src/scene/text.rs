//! OBJ and MTL text as real exporters write it: a byte-order mark, UTF-16, and bytes that are
//! not UTF-8 (3ds Max writes names and comments in the system's 8-bit code page, often
//! Latin-1), turned into the UTF-8 text `tobj` parses, line for line, so every error still
//! names the file's own line.
//!
//! The rules (docs/formats.md, "OBJ and MTL text"):
//! - a UTF-8 byte-order mark is skipped;
//! - UTF-16 with a byte-order mark (little- or big-endian) is decoded; a lone surrogate becomes
//!   U+FFFD, and an odd number of bytes (a truncated file) is an error;
//! - otherwise the text is UTF-8, except that comments, names (`o`, `g`, `usemtl`, `mtllib`,
//!   `newmtl`, texture file names) and the arguments of keys trilab ignores may hold bytes that
//!   are not UTF-8. Those are names as bytes: each such byte becomes one private-use character
//!   (`escape`), so two names are the same exactly when their bytes are (`usemtl` finds the
//!   `newmtl` of the same bytes, and `Métal` and `Mètal` in Latin-1 stay two materials), and
//!   an `mtllib` name opens the file of those bytes. Messages show each such byte as U+FFFD
//!   ([`shown`]). A keyword, a number, a face or any other line trilab parses that holds such
//!   a byte is an error naming the file, the line and the byte.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// A byte `b` (0x80-0xFF) that is not UTF-8 stands in the text as the character
/// `ESCAPE_BASE + b`: U+10FF80-U+10FFFF, the end of Supplementary Private Use Area-B, which no
/// exporter writes.
const ESCAPE_BASE: u32 = 0x10_FF00;

/// The name `usemtl` gets when it has none: no MTL can define it (it is below the escapes and
/// in a private-use plane), so tobj gives its faces no material, that is the default one.
pub(super) const NO_NAME: &str = "\u{10FF00}";

fn escape(b: u8) -> char {
    char::from_u32(ESCAPE_BASE + u32::from(b)).expect("U+10FF80..U+10FFFF are characters")
}

fn unescape(c: char) -> Option<u8> {
    let v = u32::from(c);
    (ESCAPE_BASE + 0x80..=ESCAPE_BASE + 0xFF).contains(&v).then(|| (v - ESCAPE_BASE) as u8)
}

/// A name for messages: every byte that was not UTF-8 shown as U+FFFD.
pub(super) fn shown(name: &str) -> Cow<'_, str> {
    if !name.chars().any(|c| unescape(c).is_some()) {
        return Cow::Borrowed(name);
    }
    Cow::Owned(name.chars().map(|c| if unescape(c).is_some() { char::REPLACEMENT_CHARACTER } else { c }).collect())
}

/// The file an `mtllib` name refers to: the name's own bytes (a name that was not UTF-8 opens
/// the file of those bytes).
pub(super) fn file_name(name: &str) -> PathBuf {
    if !name.chars().any(|c| unescape(c).is_some()) {
        return PathBuf::from(name);
    }
    let mut bytes = Vec::with_capacity(name.len());
    for c in name.chars() {
        match unescape(c) {
            Some(b) => bytes.push(b),
            None => bytes.extend_from_slice(c.encode_utf8(&mut [0; 4]).as_bytes()),
        }
    }
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStringExt;
        PathBuf::from(std::ffi::OsString::from_vec(bytes))
    }
    #[cfg(not(unix))]
    {
        PathBuf::from(String::from_utf8_lossy(&bytes).into_owned())
    }
}

/// Which file's rules apply: the keys whose lines must be UTF-8 text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    Obj,
    Mtl,
}

impl Format {
    /// Keys trilab parses as numbers, indices or words; every other key (comments, names, keys
    /// trilab ignores) may carry bytes that are not UTF-8.
    fn strict(self, key: &[u8]) -> bool {
        let keys: &[&[u8]] = match self {
            Format::Obj => &[b"v", b"vt", b"vn", b"vp", b"f", b"l", b"p"],
            Format::Mtl => &[b"Ka", b"Kd", b"Ks", b"Ke", b"Ns", b"Ni", b"d", b"Tr", b"Tf", b"illum", b"trilab_bsdf"],
        };
        keys.contains(&key)
    }
}

/// What [`decode`] did that the loader reports: the lines of `usemtl` without a name.
#[derive(Debug, Default)]
pub(super) struct Decoded<'a> {
    pub text: Cow<'a, str>,
    /// Lines (1-based) of `usemtl` with no name, rewritten to `usemtl` [`NO_NAME`].
    pub unnamed_usemtl: Vec<usize>,
}

/// The text of an OBJ or MTL file, as the module documentation says; borrowed when the bytes
/// are UTF-8 already (no copy of a large scene).
pub(super) fn decode<'a>(path: &Path, bytes: &'a [u8], format: Format) -> Result<Decoded<'a>> {
    let text = if let Some(body) = bytes.strip_prefix(b"\xEF\xBB\xBF") {
        utf8(path, body, format)?
    } else if let Some(body) = bytes.strip_prefix(b"\xFF\xFE") {
        Cow::Owned(utf16(path, body, u16::from_le_bytes)?)
    } else if let Some(body) = bytes.strip_prefix(b"\xFE\xFF") {
        Cow::Owned(utf16(path, body, u16::from_be_bytes)?)
    } else {
        utf8(path, bytes, format)?
    };
    let mut decoded = Decoded { text, unnamed_usemtl: Vec::new() };
    if format == Format::Obj {
        name_empty_usemtl(&mut decoded);
    }
    Ok(decoded)
}

fn utf8<'a>(path: &Path, bytes: &'a [u8], format: Format) -> Result<Cow<'a, str>> {
    if let Ok(text) = std::str::from_utf8(bytes) {
        return Ok(Cow::Borrowed(text));
    }
    let mut text = String::with_capacity(bytes.len() + bytes.len() / 8);
    for (n, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        if let Ok(line) = std::str::from_utf8(line) {
            text.push_str(line);
            continue;
        }
        let key = line.split(|b| b.is_ascii_whitespace()).find(|w| !w.is_empty()).unwrap_or_default();
        let (column, byte) = first_invalid(line);
        if key.starts_with(b"#") {
            // A comment, `#` or `#word` alike (tobj ignores both).
        } else if std::str::from_utf8(key).is_err() {
            return Err(Error::bad_input(
                path,
                Some(n + 1),
                format!("starts with bytes that are not UTF-8 text (byte 0x{byte:02X} at column {column}; is this an OBJ or MTL file?)"),
            ));
        } else if format.strict(key) {
            let key = String::from_utf8_lossy(key);
            return Err(Error::bad_input(
                path,
                Some(n + 1),
                format!(
                    "`{key}` line holds byte 0x{byte:02X} (column {column}), which is not UTF-8 text: only comments \
                     and names may hold such bytes"
                ),
            ));
        }
        for chunk in line.utf8_chunks() {
            text.push_str(chunk.valid());
            text.extend(chunk.invalid().iter().map(|&b| escape(b)));
        }
    }
    Ok(Cow::Owned(text))
}

/// The 1-based column (in bytes) and value of the first byte of `line` that is not UTF-8.
fn first_invalid(line: &[u8]) -> (usize, u8) {
    let at = std::str::from_utf8(line).err().map_or(0, |e| e.valid_up_to());
    (at + 1, line.get(at).copied().unwrap_or(0))
}

fn utf16(path: &Path, body: &[u8], unit: fn([u8; 2]) -> u16) -> Result<String> {
    let units = body.chunks_exact(2).map(|p| unit([p[0], p[1]]));
    let text: String = char::decode_utf16(units).map(|c| c.unwrap_or(char::REPLACEMENT_CHARACTER)).collect();
    if !body.len().is_multiple_of(2) {
        return Err(Error::bad_input(
            path,
            Some(1 + text.matches('\n').count()),
            format!(
                "the file is UTF-16 text (it starts with a byte-order mark) but ends in half a character \
                 ({} bytes, an odd number): truncated?",
                body.len() + 2
            ),
        ));
    }
    Ok(text)
}

/// Rewrites each `usemtl` line without a name to `usemtl` [`NO_NAME`] (tobj refuses an empty
/// name; tinyobjloader and assimp give the faces the default material, and so does trilab), and
/// records its line; and one whose name follows a tab to `usemtl name` (tobj looks for a
/// space). Visits only the places `usemtl` occurs.
fn name_empty_usemtl(decoded: &mut Decoded<'_>) {
    const KEY: &str = "usemtl";
    let text = &decoded.text;
    // (start, end, line, name): the line's bytes start..end become `usemtl name`.
    let mut edits: Vec<(usize, usize, usize, &str)> = Vec::new();
    let mut counted = (0usize, 0usize); // (byte offset, newlines before it)
    for (at, _) in text.match_indices(KEY) {
        let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
        if !text[start..at].trim().is_empty() {
            continue;
        }
        let end = text[at..].find('\n').map_or(text.len(), |i| at + i);
        let rest = &text[at + KEY.len()..end];
        let name = rest.trim();
        let tabbed = rest.starts_with(|c: char| c.is_whitespace() && c != ' ');
        if !(name.is_empty() || tabbed) {
            continue;
        }
        counted = (start, counted.1 + text.as_bytes()[counted.0..start].iter().filter(|&&b| b == b'\n').count());
        edits.push((start, end, counted.1 + 1, if name.is_empty() { NO_NAME } else { name }));
    }
    if edits.is_empty() {
        return;
    }
    let mut out = String::with_capacity(text.len() + edits.len() * (NO_NAME.len() + 1));
    let mut copied = 0;
    for &(start, end, _, name) in &edits {
        out.push_str(&text[copied..start]);
        out.push_str(KEY);
        out.push(' ');
        out.push_str(name);
        // Keep the `\r` of a CRLF line ending.
        if text[..end].ends_with('\r') {
            out.push('\r');
        }
        copied = end;
    }
    out.push_str(&text[copied..]);
    decoded.unnamed_usemtl = edits.iter().filter(|e| e.3 == NO_NAME).map(|e| e.2).collect();
    decoded.text = Cow::Owned(out);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(bytes: &[u8]) -> Result<Decoded<'_>> {
        decode(Path::new("t.obj"), bytes, Format::Obj)
    }

    #[test]
    fn utf8_text_is_borrowed_and_a_bom_is_skipped() {
        let d = obj(b"v 0 0 0\n").unwrap();
        assert!(matches!(d.text, Cow::Borrowed("v 0 0 0\n")));
        let d = obj(b"\xEF\xBB\xBFv 0 0 0\n").unwrap();
        assert!(matches!(d.text, Cow::Borrowed("v 0 0 0\n")));
    }

    #[test]
    fn utf16_with_a_bom_is_decoded_in_either_byte_order() {
        let text = "# é\nv 0 0 0\n";
        let le: Vec<u8> = [0xFF, 0xFE].into_iter().chain(text.encode_utf16().flat_map(u16::to_le_bytes)).collect();
        let be: Vec<u8> = [0xFE, 0xFF].into_iter().chain(text.encode_utf16().flat_map(u16::to_be_bytes)).collect();
        assert_eq!(obj(&le).unwrap().text, text);
        assert_eq!(obj(&be).unwrap().text, text);
        let e = obj(&le[..le.len() - 1]).unwrap_err().to_string();
        assert!(e.starts_with("t.obj:2: ") && e.contains("half a character"), "{e}");
        // A lone surrogate (0xD800) is shown as U+FFFD.
        let lone = [0xFF, 0xFE, b'#', 0, 0x00, 0xD8, b'\n', 0];
        assert_eq!(obj(&lone).unwrap().text, "#\u{FFFD}\n");
    }

    #[test]
    fn names_keep_their_bytes_and_show_as_replacement_characters() {
        let d = obj(b"# caf\xE9\nusemtl M\xE9tal\nusemtl M\xE8tal\nmtllib \xE9.mtl\n").unwrap();
        let lines: Vec<&str> = d.text.lines().collect();
        assert_ne!(lines[1], lines[2], "names that differ in their bytes stay different");
        assert_eq!(shown(lines[1]), "usemtl M\u{FFFD}tal");
        assert_eq!(file_name(&lines[3]["mtllib ".len()..]).as_os_str().len(), "\u{E9}.mtl".len() - 1);
        // The same bytes in the MTL give the same name.
        let m = decode(Path::new("t.mtl"), b"newmtl M\xE9tal\n", Format::Mtl).unwrap();
        assert_eq!(&m.text["newmtl ".len()..m.text.len() - 1], &lines[1]["usemtl ".len()..]);
    }

    #[test]
    fn bytes_that_are_not_utf8_in_parsed_lines_name_line_and_byte() {
        let e = obj(b"v 0 0 0\nv 1\xB7 0 0\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj:2: `v` line holds byte 0xB7 (column 4)"), "{e}");
        let e = obj(b"v 0 0 0\nf 1 2 3\xA0\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj:2: `f` line"), "{e}");
        let e = obj(b"\x89PNG\r\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj:1: starts with bytes that are not UTF-8"), "{e}");
        let e = decode(Path::new("t.mtl"), b"newmtl a\nKd 0.5\xB7 0 0\n", Format::Mtl).unwrap_err().to_string();
        assert!(e.starts_with("t.mtl:2: `Kd` line"), "{e}");
        // An ignored key may carry them, and so may a comment with no space after `#`.
        assert!(obj(b"s \xE9\ncstype \xFF\n#\xE9t\xE9\n").is_ok());
    }

    #[test]
    fn usemtl_without_a_name_is_rewritten_and_its_lines_recorded() {
        let d = obj(b"usemtl a\nf 1 2 3\nusemtl\nf 1 2 3\n  usemtl  \r\nnotusemtl\nusemtl b\n").unwrap();
        assert_eq!(d.unnamed_usemtl, vec![3, 5]);
        let lines: Vec<&str> = d.text.lines().collect();
        assert_eq!(lines[2], format!("usemtl {NO_NAME}"));
        assert_eq!(lines[4], format!("usemtl {NO_NAME}"));
        assert_eq!(lines[5], "notusemtl");
        assert_eq!(lines.len(), 7);
        assert!(obj(b"usemtl a\n").unwrap().unnamed_usemtl.is_empty());
        let d = obj(b"usemtl\tmy red\r\n").unwrap();
        assert!(d.unnamed_usemtl.is_empty());
        assert_eq!(d.text, "usemtl my red\r\n");
    }
}
