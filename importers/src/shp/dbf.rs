//! The `.dbf` table as the `dbase` reader sees it: a byte source in which every value of a
//! numeric field that is not a number is blanked as it is read, so that one bad value costs that
//! value and not its record.

use crate::Columns;
use std::cell::RefCell;
use std::io::{self, Read, Seek, SeekFrom};
use std::rc::Rc;

/// A value blanked because it was not a number: (record, field, text).
pub(super) type Blanked = (usize, String, String);

/// A numeric cell of a record: field name, offset after the deletion flag, length in bytes.
struct Cell {
    name: String,
    at: usize,
    len: usize,
}

/// Reads a dBase table from `inner`, blanking (with spaces, which read as empty) the values of
/// numeric fields (`N` or `F`, among the columns asked for) that are not finite numbers; all
/// `*`, the usual null, is left as it is. Records are read whole, one at a time, so that the
/// check sees a record's cells together however the reader asks for its bytes. A table whose
/// header cannot be walked passes through unchanged (the dBase reader then says what is wrong).
pub(super) struct BlankingSource<R> {
    inner: R,
    /// Where the reader is, and where `inner` is.
    pos: u64,
    inner_pos: u64,
    /// Header length, record length and declared record count.
    header: u64,
    record: usize,
    records: usize,
    cells: Vec<Cell>,
    /// The record held in `buf` (possibly short at the end of a truncated file).
    held: Option<usize>,
    buf: Vec<u8>,
    /// Records below this one have been checked (and their blanks recorded).
    checked: usize,
    blanked: Rc<RefCell<Vec<Blanked>>>,
    /// The header's bytes, as read.
    head: Vec<u8>,
}

impl<R: Read + Seek> BlankingSource<R> {
    /// The table in `inner` (positioned anywhere); the blanked values are collected in the
    /// returned list as records are read.
    pub(super) fn new(
        mut inner: R,
        columns: &Columns,
    ) -> io::Result<(Self, Rc<RefCell<Vec<Blanked>>>)> {
        inner.seek(SeekFrom::Start(0))?;
        let mut first = Vec::with_capacity(32);
        (&mut inner).take(32).read_to_end(&mut first)?;
        let mut head = first.clone();
        let (mut header, mut record, mut records) = (0u64, 0usize, 0usize);
        if first.len() == 32 {
            records = u32::from_le_bytes([first[4], first[5], first[6], first[7]]) as usize;
            header = u64::from(u16::from_le_bytes([first[8], first[9]]));
            record = usize::from(u16::from_le_bytes([first[10], first[11]]));
            let mut rest = Vec::new();
            (&mut inner)
                .take(header.saturating_sub(32))
                .read_to_end(&mut rest)?;
            head.extend_from_slice(&rest);
        }
        let inner_pos = head.len() as u64;
        let mut cells = Vec::new();
        let (mut off, mut at) = (32usize, 0usize);
        while off + 32 <= head.len() && head[off] != 0x0D {
            let d = &head[off..off + 32];
            let end = d[..11].iter().position(|&b| b == 0).unwrap_or(11);
            let name = String::from_utf8_lossy(&d[..end]).trim().to_string();
            let len = usize::from(d[16]);
            if matches!(d[11], b'N' | b'F' | b'n' | b'f') && columns.wants(&name) {
                cells.push(Cell { name, at, len });
            }
            at += len;
            off += 32;
        }
        if record == 0 || at + 1 > record || (head.len() as u64) < header {
            cells.clear();
        }
        let blanked = Rc::new(RefCell::new(Vec::new()));
        let source = BlankingSource {
            inner,
            pos: 0,
            inner_pos,
            header,
            record,
            records,
            cells,
            held: None,
            buf: Vec::new(),
            checked: 0,
            blanked: Rc::clone(&blanked),
            head,
        };
        Ok((source, blanked))
    }

    /// The header's bytes (the field descriptors among them).
    pub(super) fn head(&self) -> &[u8] {
        &self.head
    }

    /// The record at `pos`, if `pos` lies in a record that is checked.
    fn record_at(&self, pos: u64) -> Option<(usize, usize)> {
        if self.cells.is_empty() || pos < self.header {
            return None;
        }
        let rel = pos - self.header;
        let i = usize::try_from(rel / self.record as u64).ok()?;
        (i < self.records).then(|| (i, (rel % self.record as u64) as usize))
    }

    fn hold(&mut self, i: usize) -> io::Result<()> {
        let start = self.header + i as u64 * self.record as u64;
        if self.inner_pos != start {
            self.inner.seek(SeekFrom::Start(start))?;
        }
        self.buf.clear();
        (&mut self.inner)
            .take(self.record as u64)
            .read_to_end(&mut self.buf)?;
        self.inner_pos = start + self.buf.len() as u64;
        if self.buf.len() == self.record {
            let first_look = i >= self.checked;
            for c in &self.cells {
                let cell = &mut self.buf[1 + c.at..1 + c.at + c.len];
                let text = String::from_utf8_lossy(cell).trim().to_string();
                if text.is_empty()
                    || text.bytes().all(|b| b == b'*')
                    || text.parse::<f64>().is_ok_and(f64::is_finite)
                {
                    continue;
                }
                if first_look {
                    self.blanked.borrow_mut().push((i, c.name.clone(), text));
                }
                cell.fill(b' ');
            }
            self.checked = self.checked.max(i + 1);
        }
        self.held = Some(i);
        Ok(())
    }
}

impl<R: Read + Seek> Read for BlankingSource<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        if out.is_empty() {
            return Ok(0);
        }
        if let Some((i, within)) = self.record_at(self.pos) {
            if self.held != Some(i) {
                self.hold(i)?;
            }
            let from = self.buf.get(within..).unwrap_or(&[]);
            let n = from.len().min(out.len());
            out[..n].copy_from_slice(&from[..n]);
            self.pos += n as u64;
            return Ok(n);
        }
        if let Some(h) = self.head.get(self.pos as usize..).filter(|h| !h.is_empty()) {
            let n = h.len().min(out.len());
            out[..n].copy_from_slice(&h[..n]);
            self.pos += n as u64;
            return Ok(n);
        }
        if self.inner_pos != self.pos {
            self.inner.seek(SeekFrom::Start(self.pos))?;
            self.inner_pos = self.pos;
        }
        // Up to the next checked record, which must be read whole.
        let mut limit = out.len();
        if !self.cells.is_empty() && self.pos < self.header {
            limit = limit.min((self.header - self.pos) as usize);
        }
        let n = self.inner.read(&mut out[..limit])?;
        self.pos += n as u64;
        self.inner_pos = self.pos;
        Ok(n)
    }
}

impl<R: Read + Seek> Seek for BlankingSource<R> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let target = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
            SeekFrom::End(d) => {
                let end = self.inner.seek(SeekFrom::End(0))?;
                self.inner_pos = end;
                end.checked_add_signed(d)
            }
        };
        let target = target.ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "seek before the start of the .dbf",
            )
        })?;
        self.pos = target;
        Ok(target)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// A table of one numeric field `H` (5 wide) and one text field `T` (3 wide).
    fn table(values: &[(&str, &str)]) -> Vec<u8> {
        let mut b = vec![0u8; 32];
        b[0] = 3;
        b[4..8].copy_from_slice(&(values.len() as u32).to_le_bytes());
        let header = 32 + 2 * 32 + 1;
        b[8..10].copy_from_slice(&(header as u16).to_le_bytes());
        b[10..12].copy_from_slice(&(1u16 + 5 + 3).to_le_bytes());
        for (name, kind, len) in [("H", b'N', 5u8), ("T", b'C', 3u8)] {
            let mut d = [0u8; 32];
            d[..name.len()].copy_from_slice(name.as_bytes());
            d[11] = kind;
            d[16] = len;
            b.extend_from_slice(&d);
        }
        b.push(0x0D);
        for (h, t) in values {
            b.push(b' ');
            b.extend_from_slice(format!("{h:>5}").as_bytes());
            b.extend_from_slice(format!("{t:<3}").as_bytes());
        }
        b.push(0x1A);
        b
    }

    #[test]
    fn bad_numbers_are_blanked_once_whatever_the_reads() {
        let bytes = table(&[("12.5", "a"), ("x1", "b"), ("*****", "c"), ("inf", "d")]);
        let (mut src, blanked) =
            BlankingSource::new(Cursor::new(bytes.clone()), &Columns::All).unwrap();
        // Byte by byte, then again after a seek back: the same bytes, the blanks recorded once.
        let mut out = Vec::new();
        let mut one = [0u8; 1];
        while src.read(&mut one).unwrap() == 1 {
            out.push(one[0]);
        }
        src.seek(SeekFrom::Start(0)).unwrap();
        let mut again = Vec::new();
        src.read_to_end(&mut again).unwrap();
        assert_eq!(out, again);
        assert_eq!(out.len(), bytes.len());
        let header = 32 + 64 + 1;
        let rec = |i: usize| &out[header + 9 * i..header + 9 * (i + 1)];
        assert_eq!(rec(0), &bytes[header..header + 9]);
        assert_eq!(rec(1), b"      b  ");
        assert_eq!(rec(2), &bytes[header + 18..header + 27]);
        assert_eq!(rec(3), b"      d  ");
        let b = blanked.borrow();
        assert_eq!(
            *b,
            vec![
                (1, "H".to_string(), "x1".to_string()),
                (3, "H".to_string(), "inf".to_string())
            ]
        );
    }

    #[test]
    fn a_column_not_asked_for_is_left_as_it_is() {
        let bytes = table(&[("x1", "b")]);
        let only_t = Columns::only(["T"]);
        let (mut src, blanked) = BlankingSource::new(Cursor::new(bytes.clone()), &only_t).unwrap();
        let mut out = Vec::new();
        src.read_to_end(&mut out).unwrap();
        assert_eq!(out, bytes);
        assert!(blanked.borrow().is_empty());
    }
}
