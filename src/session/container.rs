//! The recording container `frames.cpsr`: every frame of a live recording, losslessly compressed
//! (LZ4 block), one self-describing record after another, so that a file cut off anywhere (crash,
//! power loss, full disk) reads back up to its last complete frame.
//!
//! Layout (all integers little-endian):
//!
//! ```text
//! file   := "CPSREC01" record*
//! record := header (48 bytes) payload (payload_len bytes)
//! header := "FRM1" index:u64 time_s:f64 pattern_index:u32 width:u32 height:u32
//!           channels:u8 codec:u8 reserved:u16 raw_len:u32 payload_len:u32 crc:u32
//! ```
//!
//! `codec` 1 is an LZ4 block of the interleaved 8-bit pixels (`raw_len` bytes once expanded),
//! `codec` 0 the pixels stored as they are. A frame is stored when its LZ4 block would not save
//! a 32nd of it (camera noise of a few gray levels leaves LZ4 nothing to find: measured ratio
//! 1.00 on the rig's frames, see `docs/benchmarks.md`), so a record is never larger than the
//! frame plus its header. Trying costs 5–6 ms per 1920×1200 frame here, two thirds of a core at
//! 121 FPS, so after a frame that did not compress the writer stores the next 15 without trying
//! and tries again on the 16th ([`PROBE_INTERVAL`]): a scene that turns compressible (dark,
//! uniform) is compressed again within 16 frames;
//! `crc` is the CRC-32 of the header's first 44 bytes followed by the payload. A reader stops at
//! the first record that is incomplete or whose CRC does not match, and says where.

use crate::frame::Frame;
use std::io::{Read, Seek, SeekFrom, Write};

pub const FILE_MAGIC: &[u8; 8] = b"CPSREC01";
const RECORD_MAGIC: &[u8; 4] = b"FRM1";
const HEADER_LEN: usize = 48;
const CODEC_STORED: u8 = 0;
const CODEC_LZ4: u8 = 1;
/// An LZ4 block is kept only if it saves at least 1/32 of the frame: a smaller saving is not
/// worth the decompression on every read.
const LZ4_MIN_SAVING_DIVISOR: usize = 32;
/// After a frame that did not compress, one frame in this many is tried again.
pub const PROBE_INTERVAL: u32 = 16;

/// Errors of the container.
#[derive(Debug, thiserror::Error)]
pub enum ContainerError {
    #[error("writing the recording failed after {frames} complete frames: {source}")]
    Write { frames: u64, source: std::io::Error },
    #[error("reading the recording: {0}")]
    Read(std::io::Error),
    #[error("not a tremorscan recording (the file does not start with CPSREC01)")]
    NotARecording,
    #[error("frame {index}: the record at byte {offset} is damaged ({why})")]
    Damaged {
        index: usize,
        offset: u64,
        why: String,
    },
}

/// Writes records to any byte sink (a file in practice; tests use failing sinks).
pub struct ContainerWriter<W: Write> {
    sink: W,
    frames: u64,
    bytes: u64,
    scratch: Vec<u8>,
    /// LZ4's output, reused from frame to frame.
    compressed: Vec<u8>,
    /// Frames still to store without trying LZ4.
    skip_lz4: u32,
}

impl<W: Write> ContainerWriter<W> {
    /// Starts a container: writes the file magic.
    pub fn new(mut sink: W) -> Result<Self, ContainerError> {
        sink.write_all(FILE_MAGIC)
            .map_err(|source| ContainerError::Write { frames: 0, source })?;
        Ok(Self {
            sink,
            frames: 0,
            bytes: FILE_MAGIC.len() as u64,
            scratch: Vec::new(),
            compressed: Vec::new(),
            skip_lz4: 0,
        })
    }

    /// Appends one frame as a complete record (header and payload in one write).
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), ContainerError> {
        let raw = frame.data.as_slice();
        let compressed_len = if self.skip_lz4 > 0 {
            self.skip_lz4 -= 1;
            None
        } else {
            let bound = lz4_flex::block::get_maximum_output_size(raw.len());
            if self.compressed.len() < bound {
                self.compressed.resize(bound, 0);
            }
            // An output too small cannot happen at the bound; it would store the frame.
            let worthwhile = raw.len() - raw.len() / LZ4_MIN_SAVING_DIVISOR;
            match lz4_flex::block::compress_into(raw, &mut self.compressed) {
                Ok(len) if len <= worthwhile => Some(len),
                _ => {
                    self.skip_lz4 = PROBE_INTERVAL - 1;
                    None
                }
            }
        };
        let (codec, payload) = match compressed_len {
            Some(len) => (CODEC_LZ4, &self.compressed[..len]),
            None => (CODEC_STORED, raw),
        };
        let mut record = std::mem::take(&mut self.scratch);
        record.clear();
        record.reserve(HEADER_LEN + payload.len());
        record.extend_from_slice(RECORD_MAGIC);
        record.extend_from_slice(&self.frames.to_le_bytes());
        record.extend_from_slice(&frame.time_s.to_le_bytes());
        record.extend_from_slice(&(frame.pattern_index as u32).to_le_bytes());
        record.extend_from_slice(&(frame.width as u32).to_le_bytes());
        record.extend_from_slice(&(frame.height as u32).to_le_bytes());
        record.push(frame.channels as u8);
        record.push(codec);
        record.extend_from_slice(&0u16.to_le_bytes());
        record.extend_from_slice(&(frame.data.len() as u32).to_le_bytes());
        record.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        let mut crc = crc32fast::Hasher::new();
        crc.update(&record);
        crc.update(payload);
        record.extend_from_slice(&crc.finalize().to_le_bytes());
        record.extend_from_slice(payload);
        let result = self.sink.write_all(&record);
        let written = record.len() as u64;
        self.scratch = record;
        result.map_err(|source| ContainerError::Write {
            frames: self.frames,
            source,
        })?;
        self.frames += 1;
        self.bytes += written;
        Ok(())
    }

    /// Pushes buffered bytes to the sink.
    pub fn flush(&mut self) -> Result<(), ContainerError> {
        self.sink.flush().map_err(|source| ContainerError::Write {
            frames: self.frames,
            source,
        })
    }

    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Bytes handed to the sink so far.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    pub fn into_inner(self) -> W {
        self.sink
    }
}

/// Where a frame's record lies, and its metadata.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordInfo {
    pub offset: u64,
    pub time_s: f64,
    pub pattern_index: usize,
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    raw_len: usize,
    codec: u8,
    payload_len: usize,
    crc: u32,
}

/// The complete records of a container, and why the scan stopped if it was not at a clean end.
#[derive(Debug, Clone, PartialEq)]
pub struct ContainerIndex {
    pub records: Vec<RecordInfo>,
    /// `Some(description)` when the file ends inside a record or a record is damaged: the
    /// recording was cut off there, and every record before it is complete.
    pub cut_off: Option<String>,
}

fn parse_header(h: &[u8; HEADER_LEN], offset: u64) -> Result<RecordInfo, String> {
    if &h[0..4] != RECORD_MAGIC {
        return Err("no record marker".into());
    }
    let u32_at = |o: usize| u32::from_le_bytes([h[o], h[o + 1], h[o + 2], h[o + 3]]);
    let f64_at = |o: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&h[o..o + 8]);
        f64::from_le_bytes(b)
    };
    let (width, height, channels) = (u32_at(24) as usize, u32_at(28) as usize, h[32] as usize);
    let raw_len = u32_at(36) as usize;
    let payload_len = u32_at(40) as usize;
    let codec_fits = match h[33] {
        CODEC_LZ4 => true,
        CODEC_STORED => payload_len == raw_len,
        _ => false,
    };
    if !codec_fits || !(channels == 1 || channels == 3) || raw_len != width * height * channels {
        return Err("inconsistent header".into());
    }
    Ok(RecordInfo {
        offset,
        time_s: f64_at(12),
        pattern_index: u32_at(20) as usize,
        width,
        height,
        channels,
        raw_len,
        codec: h[33],
        payload_len,
        crc: u32_at(HEADER_LEN - 4),
    })
}

/// Scans a container's headers (payloads are skipped; their CRC is checked when read).
pub fn scan<R: Read + Seek>(source: &mut R) -> Result<ContainerIndex, ContainerError> {
    let len = source
        .seek(SeekFrom::End(0))
        .map_err(ContainerError::Read)?;
    source
        .seek(SeekFrom::Start(0))
        .map_err(ContainerError::Read)?;
    let mut magic = [0u8; 8];
    if len < 8 {
        return Err(ContainerError::NotARecording);
    }
    source
        .read_exact(&mut magic)
        .map_err(ContainerError::Read)?;
    if &magic != FILE_MAGIC {
        return Err(ContainerError::NotARecording);
    }
    let mut records = Vec::new();
    let mut offset = 8u64;
    let cut_off = loop {
        if offset == len {
            break None;
        }
        if len - offset < HEADER_LEN as u64 {
            break Some(format!(
                "the file ends inside the header of frame {}",
                records.len()
            ));
        }
        let mut header = [0u8; HEADER_LEN];
        source
            .read_exact(&mut header)
            .map_err(ContainerError::Read)?;
        let info = match parse_header(&header, offset) {
            Ok(info) => info,
            Err(why) => break Some(format!("frame {} at byte {offset}: {why}", records.len())),
        };
        let end = offset + (HEADER_LEN + info.payload_len) as u64;
        if end > len {
            break Some(format!("the file ends inside frame {}", records.len()));
        }
        source
            .seek(SeekFrom::Start(end))
            .map_err(ContainerError::Read)?;
        records.push(info);
        offset = end;
    };
    Ok(ContainerIndex { records, cut_off })
}

/// Reads and checks the frame of `info` (CRC, size) from `source`.
pub fn read_frame<R: Read + Seek>(
    source: &mut R,
    index: usize,
    info: &RecordInfo,
) -> Result<Frame, ContainerError> {
    let damaged = |why: &str| ContainerError::Damaged {
        index,
        offset: info.offset,
        why: why.to_string(),
    };
    source
        .seek(SeekFrom::Start(info.offset))
        .map_err(ContainerError::Read)?;
    let mut record = vec![0u8; HEADER_LEN + info.payload_len];
    source
        .read_exact(&mut record)
        .map_err(ContainerError::Read)?;
    let mut crc = crc32fast::Hasher::new();
    crc.update(&record[..HEADER_LEN - 4]);
    crc.update(&record[HEADER_LEN..]);
    if crc.finalize() != info.crc {
        return Err(damaged("CRC mismatch"));
    }
    let data = if info.codec == CODEC_LZ4 {
        lz4_flex::block::decompress(&record[HEADER_LEN..], info.raw_len)
            .map_err(|e| damaged(&e.to_string()))?
    } else {
        record.split_off(HEADER_LEN)
    };
    let mut frame = Frame::from_data(info.width, info.height, info.channels, data)
        .map_err(|e| damaged(&e.to_string()))?;
    frame.time_s = info.time_s;
    frame.pattern_index = info.pattern_index;
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn frame(i: u8) -> Frame {
        let data: Vec<u8> = (0..6 * 4 * 3)
            .map(|k| (k as u8).wrapping_mul(i + 3))
            .collect();
        let mut f = Frame::from_data(6, 4, 3, data).unwrap();
        f.time_s = f64::from(i) / 121.0;
        f.pattern_index = usize::from(i % 3);
        f
    }

    fn written(n: u8) -> Vec<u8> {
        let mut w = ContainerWriter::new(Vec::new()).unwrap();
        for i in 0..n {
            w.write_frame(&frame(i)).unwrap();
        }
        w.into_inner()
    }

    #[test]
    fn frames_round_trip_exactly() {
        let mut c = Cursor::new(written(5));
        let index = scan(&mut c).unwrap();
        assert_eq!(index.records.len(), 5);
        assert_eq!(index.cut_off, None);
        for (i, info) in index.records.iter().enumerate() {
            assert_eq!(read_frame(&mut c, i, info).unwrap(), frame(i as u8));
        }
    }

    #[test]
    fn a_file_cut_anywhere_keeps_every_complete_frame() {
        let full = written(4);
        let ends = {
            let index = scan(&mut Cursor::new(full.clone())).unwrap();
            let mut ends: Vec<u64> = index.records.iter().map(|r| r.offset).collect();
            ends.push(full.len() as u64);
            ends
        };
        for cut in 8..full.len() {
            let mut c = Cursor::new(full[..cut].to_vec());
            let index = scan(&mut c).unwrap();
            let complete = ends.iter().filter(|&&e| e <= cut as u64).count() - 1;
            assert_eq!(index.records.len(), complete, "cut at {cut}");
            assert_eq!(
                index.cut_off.is_some(),
                !ends.contains(&(cut as u64)),
                "cut at {cut}"
            );
            for (i, info) in index.records.iter().enumerate() {
                assert_eq!(read_frame(&mut c, i, info).unwrap(), frame(i as u8));
            }
        }
    }

    /// A sink that accepts `room` bytes and then fails like a full disk, keeping what it took.
    struct FullDisk {
        taken: Vec<u8>,
        room: usize,
    }

    impl Write for FullDisk {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.room - self.taken.len());
            if n == 0 {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    "disk full",
                ));
            }
            self.taken.extend_from_slice(&buf[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_full_disk_is_reported_at_once_and_loses_nothing_written() {
        let full = written(4);
        let room = full.len() - 20;
        let mut w = ContainerWriter::new(FullDisk {
            taken: Vec::new(),
            room,
        })
        .unwrap();
        let mut failed_at = None;
        for i in 0..4u8 {
            if let Err(e) = w.write_frame(&frame(i)) {
                assert!(e.to_string().contains("after 3 complete frames"), "{e}");
                failed_at = Some(i);
                break;
            }
        }
        assert_eq!(failed_at, Some(3));
        let mut c = Cursor::new(w.into_inner().taken);
        let index = scan(&mut c).unwrap();
        assert_eq!(index.records.len(), 3);
        assert!(index.cut_off.is_some());
        for (i, info) in index.records.iter().enumerate() {
            assert_eq!(read_frame(&mut c, i, info).unwrap(), frame(i as u8));
        }
    }

    #[test]
    fn frames_that_do_not_compress_are_stored_and_compression_is_retried_later() {
        // Pseudo-random bytes leave LZ4 nothing to find; a flat frame compresses to almost
        // nothing.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let noise: Vec<u8> = (0..64 * 48 * 3)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 24) as u8
            })
            .collect();
        let noisy = Frame::from_data(64, 48, 3, noise).unwrap();
        let flat = Frame::from_data(64, 48, 3, vec![90; 64 * 48 * 3]).unwrap();
        let interval = PROBE_INTERVAL as usize;
        let mut sent = vec![flat.clone(), noisy.clone()];
        // After the noisy frame, flat frames: the first ones are stored untried, then LZ4 is
        // tried again and kept while it pays.
        sent.extend(std::iter::repeat_n(flat.clone(), interval + 1));
        let mut w = ContainerWriter::new(Vec::new()).unwrap();
        for f in &sent {
            w.write_frame(f).unwrap();
        }
        let mut c = Cursor::new(w.into_inner());
        let index = scan(&mut c).unwrap();
        let codecs: Vec<u8> = index.records.iter().map(|r| r.codec).collect();
        let mut expected = vec![CODEC_LZ4, CODEC_STORED];
        expected.extend(std::iter::repeat_n(CODEC_STORED, interval - 1));
        expected.extend([CODEC_LZ4, CODEC_LZ4]);
        assert_eq!(codecs, expected);
        for (i, info) in index.records.iter().enumerate() {
            assert_eq!(
                read_frame(&mut c, i, info).unwrap().data,
                sent[i].data,
                "frame {i}"
            );
        }
    }

    #[test]
    fn a_flipped_payload_bit_is_caught() {
        let mut bytes = written(2);
        let last = bytes.len() - 3;
        bytes[last] ^= 0x10;
        let mut c = Cursor::new(bytes);
        let index = scan(&mut c).unwrap();
        assert!(read_frame(&mut c, 0, &index.records[0]).is_ok());
        let e = read_frame(&mut c, 1, &index.records[1]).unwrap_err();
        assert!(e.to_string().contains("CRC"), "{e}");
    }

    #[test]
    fn other_files_are_refused() {
        let e = scan(&mut Cursor::new(b"PK\x03\x04 not a recording".to_vec())).unwrap_err();
        assert!(matches!(e, ContainerError::NotARecording));
    }
}
