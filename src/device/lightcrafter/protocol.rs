//! The DLPC350's USB HID command protocol (TI DLPU010, "DLPC350 Programmer's Guide", section 2
//! and its USB command table), as pure encoding and decoding: no I/O here.
//!
//! Every transfer is one 64-byte HID report, report id 0, which the interrupt endpoints carry
//! without the id byte:
//!
//! ```text
//! byte 0   flags: bit 7 read (1) / write (0), bit 6 host wants a reply, bit 5 NACK (replies
//!          only), bits 2..0 destination (0 = the DLPC350)
//! byte 1   sequence number (the reply echoes it)
//! byte 2,3 payload length, little-endian: the 2 command bytes plus the data
//! byte 4   CMD3 (command low byte)      byte 5   CMD2 (command high byte)
//! byte 6.. data, zero-padded to 64
//! ```
//!
//! A longer payload continues in further 64-byte reports of plain data (58 data bytes fit in the
//! first). Replies carry the header (flags, sequence, length) and then the read data from byte 4.

/// Report size of the HID interface, bytes.
pub const REPORT_LEN: usize = 64;
/// Data bytes in the first report after the 6 header and command bytes.
const FIRST_DATA: usize = REPORT_LEN - 6;

/// Flag bits of byte 0.
pub const FLAG_READ: u8 = 0x80;
pub const FLAG_REPLY: u8 = 0x40;
pub const FLAG_NACK: u8 = 0x20;

/// A DLPC350 USB command: CMD2 (high byte) and CMD3 (low byte), e.g. 0x1A1B.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Command {
    pub code: u16,
    pub name: &'static str,
}

macro_rules! commands {
    ($($ident:ident = $code:literal, $name:literal;)*) => {
        $(pub const $ident: Command = Command { code: $code, name: $name };)*
    };
}

commands! {
    POWER_CONTROL = 0x0200, "power control";
    DISPLAY_MODE = 0x1A1B, "display mode (video / pattern)";
    PATTERN_SOURCE = 0x1A22, "pattern display data input source";
    PATTERN_TRIGGER_MODE = 0x1A23, "pattern trigger mode";
    PATTERN_START_STOP = 0x1A24, "pattern display start/stop";
    EXPOSURE_PERIOD = 0x1A29, "pattern exposure and frame period";
    PATTERN_CONFIG = 0x1A31, "pattern display LUT control";
    MAILBOX_ADDRESS = 0x1A32, "pattern display LUT offset pointer";
    MAILBOX_CONTROL = 0x1A33, "pattern display LUT access control (mailbox)";
    MAILBOX_DATA = 0x1A34, "pattern display LUT data";
    TRIGGER_OUT1 = 0x1A1D, "trigger out 1 control";
    VALIDATE = 0x1A1A, "validate pattern display data";
    MAIN_STATUS = 0x1A0C, "main status";
}

/// Encodes a write (`FLAG_REPLY` set: the controller answers with an ACK or a NACK) into one or
/// more 64-byte reports.
pub fn encode_write(command: Command, sequence: u8, data: &[u8]) -> Vec<[u8; REPORT_LEN]> {
    encode(FLAG_REPLY, command, sequence, data)
}

/// Encodes a read request; `params` select what to read where a command needs that (most take
/// none).
pub fn encode_read(command: Command, sequence: u8, params: &[u8]) -> [u8; REPORT_LEN] {
    let reports = encode(FLAG_READ | FLAG_REPLY, command, sequence, params);
    reports[0]
}

fn encode(flags: u8, command: Command, sequence: u8, data: &[u8]) -> Vec<[u8; REPORT_LEN]> {
    let length = (data.len() + 2) as u16;
    let mut first = [0u8; REPORT_LEN];
    first[0] = flags;
    first[1] = sequence;
    first[2..4].copy_from_slice(&length.to_le_bytes());
    first[4..6].copy_from_slice(&command.code.to_le_bytes());
    let head = data.len().min(FIRST_DATA);
    first[6..6 + head].copy_from_slice(&data[..head]);
    let mut reports = vec![first];
    for chunk in data[head..].chunks(REPORT_LEN) {
        let mut next = [0u8; REPORT_LEN];
        next[..chunk.len()].copy_from_slice(chunk);
        reports.push(next);
    }
    reports
}

/// A reply from the controller.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    pub nack: bool,
    pub sequence: u8,
    /// The read data (empty for an ACK).
    pub data: Vec<u8>,
}

/// Decodes a reply report: header, then `length` bytes of data from byte 4.
pub fn decode_reply(report: &[u8; REPORT_LEN]) -> Reply {
    let length = usize::from(u16::from_le_bytes([report[2], report[3]]));
    let end = (4 + length).min(REPORT_LEN);
    Reply {
        nack: report[0] & FLAG_NACK != 0,
        sequence: report[1],
        data: report[4..end].to_vec(),
    }
}

/// Which LEDs light a pattern (LUT bits 14..12: bit 0 red, bit 1 green, bit 2 blue).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Led {
    None = 0,
    Red = 1,
    Green = 2,
    Blue = 4,
    White = 7,
}

/// What starts a pattern (LUT bits 1..0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PatternTrigger {
    Internal = 0,
    /// External positive edge; with pattern trigger mode 0 this is the video input's VSYNC.
    ExternalPositive = 1,
    ExternalNegative = 2,
    /// No trigger: continue from the previous pattern (it still gets its full exposure).
    Continue = 3,
}

/// One 24-bit entry of the pattern LUT (DLPU010 table "Pattern LUT Definition").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LutEntry {
    pub trigger: PatternTrigger,
    /// Pattern number in the 24-bit frame: bit plane group `pattern × bit_depth` onwards.
    pub pattern: u8,
    /// 1..=8 bits.
    pub bit_depth: u8,
    pub led: Led,
    pub invert: bool,
    /// Insert a black pattern after this one (needs 230 µs before the next).
    pub insert_black: bool,
    /// Swap to the next frame buffer (the next video frame) before this pattern.
    pub buffer_swap: bool,
    /// Keep TRIG_OUT_1 high from the previous pattern: one camera exposure spans both.
    pub trigger_out_previous: bool,
}

impl LutEntry {
    /// The entry's 24-bit word: bits 1..0 trigger, 7..2 pattern, 11..8 bit depth, 14..12 LEDs,
    /// 16 invert, 17 black fill, 18 buffer swap, 19 trigger-out shared with the previous.
    pub fn word(&self) -> u32 {
        (self.trigger as u32)
            | (u32::from(self.pattern & 0x3F) << 2)
            | (u32::from(self.bit_depth & 0x0F) << 8)
            | ((self.led as u32) << 12)
            | (u32::from(self.invert) << 16)
            | (u32::from(self.insert_black) << 17)
            | (u32::from(self.buffer_swap) << 18)
            | (u32::from(self.trigger_out_previous) << 19)
    }

    /// The three little-endian bytes the mailbox takes.
    pub fn bytes(&self) -> [u8; 3] {
        let w = self.word().to_le_bytes();
        [w[0], w[1], w[2]]
    }
}

/// The result of "validate pattern display data" (0x1A1A), one status byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Validation(pub u8);

impl Validation {
    /// Bit 7: the controller is still validating; ask again.
    pub fn busy(self) -> bool {
        self.0 & 0x80 != 0
    }

    /// Bits 0 and 1 make the sequence unusable; bits 2..4 are warnings.
    pub fn is_valid(self) -> bool {
        self.0 & 0x03 == 0
    }

    /// Every reason bit that is set, in words.
    pub fn reasons(self) -> Vec<&'static str> {
        const REASONS: [&str; 5] = [
            "exposure or frame period settings are invalid",
            "pattern numbers in the LUT are invalid",
            "warning: continuous trigger out 1 request or overlapping black sectors",
            "warning: post vector was not inserted before an externally triggered vector",
            "warning: frame period and exposure differ by less than 230 µs",
        ];
        (0..5)
            .filter(|bit| self.0 & (1 << bit) != 0)
            .map(|bit| REASONS[bit])
            .collect()
    }
}

/// Trigger-out edge delay code: 107.2 ns per step, 0xBB is no delay (range −20.05..+2.787 µs).
pub fn trigger_delay_code(delay_micros: f64) -> Option<u8> {
    let code = (187.0 + delay_micros * 1000.0 / 107.2).round();
    (0.0..=213.0).contains(&code).then_some(code as u8)
}
