//! OBJ and MTL text as real exporters write it: a byte-order mark, UTF-16, and bytes that are
//! not UTF-8 (3ds Max writes names and comments in the system's 8-bit code page, often
//! Latin-1), turned into the UTF-8 text `tobj` parses, line for line, so every error still
//! names the file's own line.
//!
//! The rules (docs/formats.md, "OBJ and MTL text"):
//! - a UTF-8 byte-order mark is skipped;
//! - UTF-16 with a byte-order mark (little- or big-endian) is decoded; a lone surrogate becomes
//!   U+FFFD, and an odd number of bytes (a truncated file) is an error;
//! - UTF-16 without a byte-order mark (a NUL byte beside most bytes of the file's start) is
//!   refused at once, naming the byte order and how to convert it: without the mark the byte
//!   order is a guess, and read as UTF-8 such text is one long line of NULs;
//! - a line ends at LF, CRLF or a CR alone (classic Mac OS): a lone CR becomes LF before
//!   anything else reads the text, so every line number counts CR-separated lines too;
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

/// The name `usemtl` and `newmtl` get when they have none (Blender 2.61 writes both bare for an
/// unnamed material): no exporter writes it (it is below the escapes and in a private-use
/// plane), so a bare `usemtl` selects the material of a bare `newmtl`, and, when no MTL has
/// one, tobj gives its faces no material, that is the default one.
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

/// What [`decode`] did that the loader reports: the lines of `usemtl` (in an OBJ) and
/// `newmtl` (in an MTL) without a name.
#[derive(Debug, Default)]
pub(super) struct Decoded<'a> {
    pub text: Cow<'a, str>,
    /// Lines (1-based) of `usemtl` with no name, rewritten to `usemtl` [`NO_NAME`].
    pub unnamed_usemtl: Vec<usize>,
    /// Lines (1-based) of `newmtl` with no name, rewritten to `newmtl` [`NO_NAME`].
    pub unnamed_newmtl: Vec<usize>,
}

/// The text of an OBJ or MTL file, as the module documentation says; borrowed when the bytes
/// are UTF-8 with LF or CRLF line ends already (no copy of a large scene).
pub(super) fn decode<'a>(path: &Path, bytes: &'a [u8], format: Format) -> Result<Decoded<'a>> {
    let text = if let Some(body) = bytes.strip_prefix(b"\xEF\xBB\xBF") {
        utf8_lines(path, body, format)?
    } else if let Some(body) = bytes.strip_prefix(b"\xFF\xFE") {
        Cow::Owned(utf16(path, body, u16::from_le_bytes)?)
    } else if let Some(body) = bytes.strip_prefix(b"\xFE\xFF") {
        Cow::Owned(utf16(path, body, u16::from_be_bytes)?)
    } else if let Some(order) = utf16_without_bom(bytes) {
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        let utf8_name = match name.rsplit_once('.') {
            Some((stem, ext)) => format!("{stem}.utf8.{ext}"),
            None => format!("{name}.utf8"),
        };
        return Err(Error::bad_input(
            path,
            None,
            format!(
                "looks like UTF-16 {} text without a byte-order mark (a NUL byte beside most bytes of its \
                 start), which trilab does not guess at: convert it to UTF-8 (`iconv -f {} -t UTF-8 {name} > \
                 {utf8_name}`) or save it as UTF-16 with a byte-order mark",
                order.name(),
                order.iconv()
            ),
        ));
    } else {
        utf8_lines(path, bytes, format)?
    };
    let mut decoded = Decoded { text, ..Default::default() };
    match format {
        Format::Obj => decoded.unnamed_usemtl = name_empty(&mut decoded.text, "usemtl"),
        Format::Mtl => decoded.unnamed_newmtl = name_empty(&mut decoded.text, "newmtl"),
    }
    Ok(decoded)
}

/// A byte order of UTF-16.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ByteOrder {
    Little,
    Big,
}

impl ByteOrder {
    fn name(self) -> &'static str {
        match self {
            ByteOrder::Little => "little-endian",
            ByteOrder::Big => "big-endian",
        }
    }

    /// The encoding's name for `iconv -f`.
    fn iconv(self) -> &'static str {
        match self {
            ByteOrder::Little => "UTF-16LE",
            ByteOrder::Big => "UTF-16BE",
        }
    }
}

/// How many bytes of a file's start [`utf16_without_bom`] reads.
const UTF16_SAMPLE: usize = 512;

/// The byte order of text that looks like UTF-16 without a byte-order mark: in at least three
/// quarters of the two-byte units of its first [`UTF16_SAMPLE`] bytes one byte is NUL and the
/// other not (every character up to U+00FF, all an OBJ or MTL file needs, is such a unit; UTF-8
/// and 8-bit text hold no NUL, and UTF-32 is NUL in half its units). Reads only that start.
fn utf16_without_bom(bytes: &[u8]) -> Option<ByteOrder> {
    let units = &bytes[..bytes.len().min(UTF16_SAMPLE)];
    let count = units.len() / 2;
    let (mut little, mut big) = (0, 0);
    for u in units.chunks_exact(2) {
        match (u[0], u[1]) {
            (0, 0) => {}
            (_, 0) => little += 1,
            (0, _) => big += 1,
            _ => {}
        }
    }
    if count == 0 {
        None
    } else if little * 4 >= count * 3 {
        Some(ByteOrder::Little)
    } else if big * 4 >= count * 3 {
        Some(ByteOrder::Big)
    } else {
        None
    }
}

/// Whether a CR ends a line by itself somewhere in `bytes` (not as the CR of a CRLF).
fn has_lone_cr(bytes: &[u8]) -> bool {
    let mut rest = bytes;
    while let Some(i) = rest.iter().position(|&b| b == b'\r') {
        if rest.get(i + 1) != Some(&b'\n') {
            return true;
        }
        rest = &rest[i + 2..];
    }
    false
}

/// Turns every CR that ends a line by itself into LF, keeping CRLF (tobj and every line count
/// here split at LF only; a file from classic Mac OS would be one line).
fn lone_cr_to_lf(bytes: &mut [u8]) {
    for i in 0..bytes.len() {
        if bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n') {
            bytes[i] = b'\n';
        }
    }
}

/// [`utf8`] of `bytes` after [`lone_cr_to_lf`]; borrowed when there is no lone CR.
fn utf8_lines<'a>(path: &Path, bytes: &'a [u8], format: Format) -> Result<Cow<'a, str>> {
    if !has_lone_cr(bytes) {
        return utf8(path, bytes, format);
    }
    let mut owned = bytes.to_vec();
    lone_cr_to_lf(&mut owned);
    match String::from_utf8(owned) {
        Ok(text) => Ok(Cow::Owned(text)),
        Err(e) => Ok(Cow::Owned(utf8(path, e.as_bytes(), format)?.into_owned())),
    }
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
    let mut text: String = char::decode_utf16(units).map(|c| c.unwrap_or(char::REPLACEMENT_CHARACTER)).collect();
    if has_lone_cr(text.as_bytes()) {
        let mut bytes = text.into_bytes();
        // CR and LF are ASCII, which UTF-8 never uses inside a longer character.
        lone_cr_to_lf(&mut bytes);
        text = String::from_utf8(bytes).expect("an ASCII byte replaced by another keeps UTF-8 valid");
    }
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

/// Rewrites each `key` line (`usemtl` or `newmtl`) without a name to `key` [`NO_NAME`] (tobj
/// refuses an empty name; tinyobjloader and assimp read a bare `usemtl` as the default material,
/// or the material of a bare `newmtl`, and so does trilab), returning their lines; and one whose
/// name follows a tab to `key name` (tobj looks for a space after `usemtl`). Visits only the
/// places `key` occurs.
fn name_empty(text: &mut Cow<'_, str>, key: &str) -> Vec<usize> {
    // (start, end, line, name): the line's bytes start..end become `key name`.
    let mut edits: Vec<(usize, usize, usize, &str)> = Vec::new();
    let mut counted = (0usize, 0usize); // (byte offset, newlines before it)
    for (at, _) in text.match_indices(key) {
        let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
        if !text[start..at].trim().is_empty() {
            continue;
        }
        let end = text[at..].find('\n').map_or(text.len(), |i| at + i);
        let rest = &text[at + key.len()..end];
        let name = rest.trim();
        let tabbed = rest.starts_with(|c: char| c.is_whitespace() && c != ' ');
        if !(name.is_empty() || tabbed) {
            continue;
        }
        counted = (start, counted.1 + text.as_bytes()[counted.0..start].iter().filter(|&&b| b == b'\n').count());
        edits.push((start, end, counted.1 + 1, if name.is_empty() { NO_NAME } else { name }));
    }
    if edits.is_empty() {
        return Vec::new();
    }
    let mut out = String::with_capacity(text.len() + edits.len() * (NO_NAME.len() + 1));
    let mut copied = 0;
    for &(start, end, _, name) in &edits {
        out.push_str(&text[copied..start]);
        out.push_str(key);
        out.push(' ');
        out.push_str(name);
        // Keep the `\r` of a CRLF line ending.
        if text[..end].ends_with('\r') {
            out.push('\r');
        }
        copied = end;
    }
    out.push_str(&text[copied..]);
    let unnamed = edits.iter().filter(|e| e.3 == NO_NAME).map(|e| e.2).collect();
    *text = Cow::Owned(out);
    unnamed
}

/// `text` with each line `edit` gives a replacement for (it is called with the 0-based line
/// number and the line without its end) replaced by that, line for line, so every line number a
/// message gives stays the file's own. Borrowed when no line changes; one pass either way.
pub(super) fn edit_lines<'a>(text: &'a str, mut edit: impl FnMut(usize, &str) -> Option<String>) -> Cow<'a, str> {
    let mut out: Option<String> = None;
    let mut start = 0;
    for (n, raw) in text.split_inclusive('\n').enumerate() {
        let line = raw.strip_suffix('\n').unwrap_or(raw);
        let line = line.strip_suffix('\r').unwrap_or(line);
        match (edit(n, line), &mut out) {
            (Some(new), out) => {
                let out = out.get_or_insert_with(|| {
                    let mut s = String::with_capacity(text.len());
                    s.push_str(&text[..start]);
                    s
                });
                out.push_str(&new);
                out.push('\n');
            }
            (None, Some(out)) => out.push_str(raw),
            (None, None) => {}
        }
        start += raw.len();
    }
    out.map_or(Cow::Borrowed(text), Cow::Owned)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edited_lines_keep_their_numbers_and_untouched_text_is_borrowed() {
        let text = "a\r\nb\nc\r\nd";
        assert!(matches!(edit_lines(text, |_, _| None), Cow::Borrowed(_)));
        let seen = std::cell::RefCell::new(vec![]);
        let out = edit_lines(text, |n, l| {
            seen.borrow_mut().push(l.to_owned());
            (n == 1 || n == 3).then(|| l.to_uppercase())
        });
        assert_eq!(seen.into_inner(), ["a", "b", "c", "d"]);
        assert_eq!(out, "a\r\nB\nc\r\nD\n");
    }

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

    #[test]
    fn newmtl_without_a_name_is_rewritten_and_its_lines_recorded() {
        let mtl = |bytes: &'static [u8]| decode(Path::new("t.mtl"), bytes, Format::Mtl).unwrap();
        // Blender 2.61 writes `newmtl ` (a space, then no name).
        let d = mtl(b"newmtl a\nKd 1 0 0\nnewmtl \nKd 0 0 1\n  newmtl\r\nnewmtlx\nnewmtl\tb\nusemtl\n");
        assert_eq!(d.unnamed_newmtl, vec![3, 5]);
        assert!(d.unnamed_usemtl.is_empty());
        let lines: Vec<&str> = d.text.lines().collect();
        assert_eq!(
            lines,
            [
                "newmtl a",
                "Kd 1 0 0",
                &format!("newmtl {NO_NAME}"),
                "Kd 0 0 1",
                &format!("newmtl {NO_NAME}"),
                "newmtlx",
                "newmtl b",
                "usemtl"
            ]
        );
        // An OBJ's `newmtl` is not a material definition; an MTL's `usemtl` is not a use.
        let d = obj(b"newmtl\nusemtl\n").unwrap();
        assert_eq!((d.unnamed_usemtl, d.unnamed_newmtl), (vec![2], vec![]));
        assert!(mtl(b"newmtl a\n").unnamed_newmtl.is_empty());
    }

    #[test]
    fn a_lone_cr_ends_a_line_and_crlf_stays_one_line_end() {
        // Classic Mac OS: CR alone.
        let d = obj(b"v 0 0 0\rv 1 0 0\rf 1 2 3\r").unwrap();
        assert_eq!(d.text, "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
        // Mixed: CRLF, CR, LF, CR CRLF (two line ends), LF CR (two), a CR at the very end.
        let d = obj(b"a\r\nb\rc\nd\r\r\ne\n\rf\r").unwrap();
        assert_eq!(d.text, "a\r\nb\nc\nd\n\r\ne\n\nf\n");
        assert_eq!(d.text.lines().collect::<Vec<_>>(), ["a", "b", "c", "d", "", "e", "", "f"]);
        // CRLF only: no copy.
        assert!(matches!(obj(b"v 0 0 0\r\nv 1 0 0\r\n").unwrap().text, Cow::Borrowed(_)));
        // Line numbers count CR-separated lines: in bytes that are not UTF-8, after a UTF-8
        // byte-order mark, in an unnamed `usemtl`, and in truncated UTF-16.
        let e = obj(b"# caf\xE9\rv 0 0 0\rv 1\xB7 0 0\r").unwrap_err().to_string();
        assert!(e.starts_with("t.obj:3: `v` line holds byte 0xB7"), "{e}");
        let d = obj(b"\xEF\xBB\xBFv 0 0 0\r\rusemtl\rf 1 1 1\r").unwrap();
        assert_eq!(d.unnamed_usemtl, vec![3]);
        assert_eq!(d.text, format!("v 0 0 0\n\nusemtl {NO_NAME}\nf 1 1 1\n"));
        let text = "# \u{E9}\rv 0 0 0\r\nv 1 0 0\r";
        let le: Vec<u8> = [0xFF, 0xFE].into_iter().chain(text.encode_utf16().flat_map(u16::to_le_bytes)).collect();
        assert_eq!(obj(&le).unwrap().text, "# \u{E9}\nv 0 0 0\r\nv 1 0 0\n");
        let e = obj(&le[..le.len() - 1]).unwrap_err().to_string();
        assert!(e.starts_with("t.obj:3: ") && e.contains("half a character"), "{e}");
        let m = decode(Path::new("t.mtl"), b"newmtl a\rKd 1 0 0\rnewmtl\r", Format::Mtl).unwrap();
        assert_eq!(m.unnamed_newmtl, vec![3]);
    }

    #[test]
    fn utf16_without_a_bom_is_refused_naming_the_byte_order() {
        let text = "# Caf\u{E9} \u{263A}\r\nmtllib a.mtl\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n";
        let le: Vec<u8> = text.encode_utf16().flat_map(u16::to_le_bytes).collect();
        let be: Vec<u8> = text.encode_utf16().flat_map(u16::to_be_bytes).collect();
        for (bytes, order, iconv) in [(&le, "little-endian", "UTF-16LE"), (&be, "big-endian", "UTF-16BE")] {
            let e = decode(Path::new("d/scene.obj"), bytes, Format::Obj).unwrap_err().to_string();
            assert_eq!(
                e,
                format!(
                    "d/scene.obj: looks like UTF-16 {order} text without a byte-order mark (a NUL byte beside \
                     most bytes of its start), which trilab does not guess at: convert it to UTF-8 (`iconv -f \
                     {iconv} -t UTF-8 scene.obj > scene.utf8.obj`) or save it as UTF-16 with a byte-order mark"
                )
            );
            let e = decode(Path::new("m.mtl"), bytes, Format::Mtl).unwrap_err().to_string();
            assert!(e.starts_with(&format!("m.mtl: looks like UTF-16 {order} text")) && e.contains(iconv), "{e}");
        }
        // Only the start is read: a file of any length is refused as fast.
        let long: Vec<u8> = le.iter().copied().cycle().take(UTF16_SAMPLE * 1000).collect();
        assert!(obj(&long).unwrap_err().to_string().contains("UTF-16 little-endian"));
        // A single character is enough to tell.
        assert!(obj(b"v\0").unwrap_err().to_string().contains("UTF-16 little-endian"));
        // UTF-8 with a stray NUL, an empty file, and UTF-32 are not UTF-16.
        assert!(obj(b"v 0 0 0\0\nv 1 0 0\n").is_ok());
        assert!(obj(b"").is_ok());
        let utf32: Vec<u8> = "v 0 0 0\n".chars().flat_map(|c| u32::from(c).to_le_bytes()).collect();
        assert!(obj(&utf32).is_ok());
    }
}
