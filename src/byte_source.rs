//! A `.ezw` file on disk read by ranges ([`wavemesh_codec::ByteSource`]), counting the
//! distinct bytes it reads so reports can say how much of a file a decode touched.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::Path;

use wavemesh_codec::ByteSource;

/// A file read by ranges. What is read from the start of the file on (up to 16 MiB, as
/// long as the reads continue one another and stop short of the file's end) is kept, so
/// the header and index, which every reader of a tiled file looks at first and again for
/// each tile row, are read from disk once; a read of a whole stream is not kept twice.
#[derive(Debug)]
pub struct FileSource {
    file: File,
    len: u64,
    /// The byte ranges read from disk so far: sorted, disjoint, none touching another.
    read: Vec<(u64, u64)>,
    head: Vec<u8>,
}

impl FileSource {
    /// Opens `path` for reading.
    pub fn open(path: &Path) -> io::Result<FileSource> {
        let file = File::open(path)?;
        let len = file.metadata()?.len();
        Ok(FileSource {
            file,
            len,
            read: Vec::new(),
            head: Vec::new(),
        })
    }

    /// The file's length in bytes.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether the file is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Distinct bytes of the file read so far (a range read twice counts once).
    pub fn bytes_read(&self) -> u64 {
        self.read.iter().map(|(start, end)| end - start).sum()
    }

    /// Adds `start..end` to the ranges read.
    fn note_read(&mut self, start: u64, end: u64) {
        if start >= end {
            return;
        }
        // The ranges that overlap or touch it merge with it into one.
        let first = self.read.partition_point(|r| r.1 < start);
        let last = self.read.partition_point(|r| r.0 <= end);
        let merged = self.read[first..last]
            .iter()
            .fold((start, end), |(s, e), r| (s.min(r.0), e.max(r.1)));
        self.read.splice(first..last, [merged]);
    }
}

impl ByteSource for FileSource {
    fn read_at(&mut self, offset: u64, len: usize) -> io::Result<Vec<u8>> {
        let available = self.len.saturating_sub(offset).min(len as u64);
        let end = offset + available;
        // What the kept start of the file holds, then the rest from disk.
        let kept = self.head.len() as u64;
        let cached_end = if offset < kept { end.min(kept) } else { offset };
        let mut out = Vec::with_capacity(available as usize);
        if offset < kept {
            out.extend_from_slice(&self.head[offset as usize..cached_end as usize]);
        }
        if cached_end < end {
            self.file.seek(SeekFrom::Start(cached_end))?;
            let before = out.len();
            let read = (&mut self.file)
                .take(end - cached_end)
                .read_to_end(&mut out)?;
            self.note_read(cached_end, cached_end + read as u64);
            // Reads that continue the kept start (the header, then the index) extend it;
            // one that runs to the end of the file (a whole stream) is the caller's to
            // keep, not a second copy's.
            if cached_end == kept && kept as usize + read <= HEAD_KEPT && end < self.len {
                self.head.extend_from_slice(&out[before..]);
            }
        }
        Ok(out)
    }
}

/// Most bytes of the file's start kept.
const HEAD_KEPT: usize = 16 << 20;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_ranges_and_counts_them() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.bin");
        std::fs::write(&path, (0..100u8).collect::<Vec<_>>()).unwrap();
        let mut source = FileSource::open(&path).unwrap();
        assert_eq!(source.read_at(10, 3).unwrap(), vec![10, 11, 12]);
        assert_eq!(source.read_at(98, 10).unwrap(), vec![98, 99]);
        assert!(source.read_at(200, 10).unwrap().is_empty());
        assert_eq!(source.bytes_read(), 5);
        // The start of the file is read once (10..13 within it counts once).
        assert_eq!(source.read_at(0, 50).unwrap().len(), 50);
        assert_eq!(source.read_at(5, 20).unwrap()[0], 5);
        assert_eq!(source.bytes_read(), 52);
        // Past the kept start: only the rest comes from disk, and is kept too.
        assert_eq!(
            source.read_at(40, 20).unwrap(),
            (40..60u8).collect::<Vec<_>>()
        );
        assert_eq!(source.bytes_read(), 62);
        assert_eq!(source.read_at(0, 60).unwrap().len(), 60);
        assert_eq!(source.bytes_read(), 62);
        // A read elsewhere is not kept, and counts once however often it is read.
        assert_eq!(source.read_at(80, 5).unwrap(), vec![80, 81, 82, 83, 84]);
        assert_eq!(source.read_at(80, 5).unwrap().len(), 5);
        assert_eq!(source.bytes_read(), 67);
        // Ranges touching or overlapping those read merge with them.
        assert_eq!(source.read_at(70, 40).unwrap().len(), 30);
        assert_eq!(source.bytes_read(), 90);
        assert_eq!(source.read_at(0, 100).unwrap().len(), 100);
        assert_eq!(source.bytes_read(), 100);
    }
}
