//! The LightCrafter 4500's DLPC350 protocol: byte-exact packets against the published format
//! (TI DLPU010), the whole CPS programming against a mock controller that checks order and
//! answers ACK, NACK and busy, and the validation bits.
#![allow(clippy::unwrap_used, reason = "tests")]

use std::collections::VecDeque;
use tremorscan::device::lightcrafter::protocol::{
    self, decode_reply, encode_read, encode_write, trigger_delay_code, Validation, REPORT_LEN,
};
use tremorscan::device::lightcrafter::timing::CpsTiming;
use tremorscan::device::lightcrafter::{cps_lut, HidTransport, LightCrafter, LightcrafterError};
use tremorscan::device::Projector;

/// A report: the given leading bytes, zero-padded to 64.
fn report(head: &[u8]) -> [u8; REPORT_LEN] {
    let mut r = [0u8; REPORT_LEN];
    r[..head.len()].copy_from_slice(head);
    r
}

#[test]
fn every_command_encodes_byte_for_byte() {
    // flags 0x40 (write, reply wanted), sequence, length LSB/MSB (2 command bytes + data),
    // CMD3, CMD2, data.
    let cases: Vec<(protocol::Command, Vec<u8>, Vec<u8>)> = vec![
        (
            protocol::PATTERN_START_STOP,
            vec![0],
            vec![0x40, 7, 3, 0, 0x24, 0x1A, 0],
        ),
        (
            protocol::PATTERN_START_STOP,
            vec![2],
            vec![0x40, 7, 3, 0, 0x24, 0x1A, 2],
        ),
        (
            protocol::DISPLAY_MODE,
            vec![1],
            vec![0x40, 7, 3, 0, 0x1B, 0x1A, 1],
        ),
        (
            protocol::PATTERN_SOURCE,
            vec![0],
            vec![0x40, 7, 3, 0, 0x22, 0x1A, 0],
        ),
        (
            protocol::PATTERN_TRIGGER_MODE,
            vec![0],
            vec![0x40, 7, 3, 0, 0x23, 0x1A, 0],
        ),
        (
            protocol::EXPOSURE_PERIOD,
            // 2500 µs = 0x09C4, twice.
            vec![0xC4, 0x09, 0, 0, 0xC4, 0x09, 0, 0],
            vec![
                0x40, 7, 10, 0, 0x29, 0x1A, 0xC4, 0x09, 0, 0, 0xC4, 0x09, 0, 0,
            ],
        ),
        (
            protocol::TRIGGER_OUT1,
            vec![0, 0xBB, 0xBB],
            vec![0x40, 7, 5, 0, 0x1D, 0x1A, 0, 0xBB, 0xBB],
        ),
        (
            protocol::MAILBOX_CONTROL,
            vec![2],
            vec![0x40, 7, 3, 0, 0x33, 0x1A, 2],
        ),
        (
            protocol::MAILBOX_ADDRESS,
            vec![0],
            vec![0x40, 7, 3, 0, 0x32, 0x1A, 0],
        ),
        (
            protocol::PATTERN_CONFIG,
            vec![8, 1, 8, 0],
            vec![0x40, 7, 6, 0, 0x31, 0x1A, 8, 1, 8, 0],
        ),
        (
            protocol::VALIDATE,
            vec![0],
            vec![0x40, 7, 3, 0, 0x1A, 0x1A, 0],
        ),
        (
            protocol::POWER_CONTROL,
            vec![0],
            vec![0x40, 7, 3, 0, 0x00, 0x02, 0],
        ),
    ];
    for (command, data, expected) in cases {
        let reports = encode_write(command, 7, &data);
        assert_eq!(reports, vec![report(&expected)], "{}", command.name);
    }
    // Reads: flags 0xC0 (read, reply wanted), no data.
    assert_eq!(
        encode_read(protocol::VALIDATE, 9, &[]),
        report(&[0xC0, 9, 2, 0, 0x1A, 0x1A])
    );
    assert_eq!(
        encode_read(protocol::MAIN_STATUS, 0, &[]),
        report(&[0xC0, 0, 2, 0, 0x0C, 0x1A])
    );
}

#[test]
fn the_cps_lut_and_long_payloads_encode_as_published() {
    // Image 0: red pattern 0 waits for VSYNC and swaps buffers; green and blue continue and share
    // trigger out 1. Words: trigger | pattern << 2 | depth << 8 | LED << 12 | swap << 18 |
    // shared trigger-out << 19.
    let lut = cps_lut(6);
    assert_eq!(lut.len(), 9);
    let words: Vec<u32> = lut.iter().map(|e| e.word()).collect();
    assert_eq!(&words[..3], &[0x04_1601, 0x08_2607, 0x08_460B]);
    assert_eq!(&words[3..6], &words[..3]);
    assert_eq!(lut[0].bytes(), [0x01, 0x16, 0x04]);
    // The 27 LUT bytes fit one report: length 29 = 0x1D.
    let data: Vec<u8> = lut.iter().flat_map(|e| e.bytes()).collect();
    let reports = encode_write(protocol::MAILBOX_DATA, 3, &data);
    assert_eq!(reports.len(), 1);
    assert_eq!(
        &reports[0][..9],
        &[0x40, 3, 0x1D, 0, 0x34, 0x1A, 0x01, 0x16, 0x04]
    );
    assert_eq!(&reports[0][6..33], &data[..]);
    assert!(reports[0][33..].iter().all(|&b| b == 0));
    // A 70-byte payload: 58 data bytes after the header, then 12 in a plain second report.
    let long: Vec<u8> = (1..=70).collect();
    let reports = encode_write(protocol::MAILBOX_DATA, 0, &long);
    assert_eq!(reports.len(), 2);
    assert_eq!(&reports[0][..4], &[0x40, 0, 72, 0]);
    assert_eq!(reports[0][63], 58);
    assert_eq!(&reports[1][..12], &long[58..]);
    assert!(reports[1][12..].iter().all(|&b| b == 0));
    // Trigger delays: 107.2 ns steps around 0xBB.
    assert_eq!(trigger_delay_code(0.0), Some(0xBB));
    assert_eq!(trigger_delay_code(-20.05), Some(0x00));
    assert_eq!(trigger_delay_code(2.787), Some(0xD5));
    assert_eq!(trigger_delay_code(5.0), None);
}

#[test]
fn validation_bits_decode_to_reasons() {
    assert!(Validation(0x80).busy());
    assert!(Validation(0x00).is_valid() && Validation(0x00).reasons().is_empty());
    let both = Validation(0x03);
    assert!(!both.is_valid());
    assert_eq!(
        both.reasons(),
        vec![
            "exposure or frame period settings are invalid",
            "pattern numbers in the LUT are invalid"
        ]
    );
    // Warnings (bits 2..4) leave the sequence usable.
    let warn = Validation(0x1C);
    assert!(warn.is_valid());
    assert_eq!(warn.reasons().len(), 3);
    assert!(warn.reasons()[2].contains("230 µs"));
    // A reply: NACK flag, echoed sequence, data after the 4 header bytes.
    let r = decode_reply(&report(&[0x20, 5, 1, 0, 0x81]));
    assert!(r.nack);
    assert_eq!((r.sequence, r.data), (5, vec![0x81]));
}

/// A DLPC350 stand-in: records every report, ACKs writes (or NACKs one command), and answers
/// validation reads from a script.
#[derive(Default)]
struct MockController {
    /// (command code, read?, sequence, data) of every command received, in order.
    commands: Vec<(u16, bool, u8, Vec<u8>)>,
    /// Continuation bytes still expected for the last command.
    pending: usize,
    nack: Option<u16>,
    validation: VecDeque<u8>,
}

impl HidTransport for MockController {
    fn write_report(&mut self, r: &[u8; REPORT_LEN]) -> Result<(), LightcrafterError> {
        if self.pending > 0 {
            let take = self.pending.min(REPORT_LEN);
            let last = self.commands.last_mut().unwrap();
            last.3.extend_from_slice(&r[..take]);
            self.pending -= take;
            return Ok(());
        }
        let length = usize::from(u16::from_le_bytes([r[2], r[3]])) - 2;
        let code = u16::from_le_bytes([r[4], r[5]]);
        let head = length.min(58);
        self.commands
            .push((code, r[0] & 0x80 != 0, r[1], r[6..6 + head].to_vec()));
        self.pending = length - head;
        Ok(())
    }

    fn read_report(&mut self) -> Result<[u8; REPORT_LEN], LightcrafterError> {
        assert_eq!(
            self.pending, 0,
            "reply asked for before the payload was complete"
        );
        let (code, read, sequence, _) = self.commands.last().cloned().unwrap();
        if Some(code) == self.nack {
            return Ok(report(&[0x20, sequence, 0, 0]));
        }
        if read && code == protocol::VALIDATE.code {
            let status = self
                .validation
                .pop_front()
                .expect("an unexpected validation read");
            return Ok(report(&[0x00, sequence, 1, 0, status]));
        }
        Ok(report(&[0x00, sequence, 0, 0]))
    }
}

fn programmed(mock: MockController) -> (Result<(), LightcrafterError>, MockController) {
    let mut lc = LightCrafter::new(mock);
    let timing = CpsTiming::new(121.0, 6).unwrap();
    let result = lc.program_cps(&timing);
    (result, lc.into_transport())
}

#[test]
fn cps_programming_sends_every_command_in_order_and_polls_validation() {
    let mock = MockController {
        validation: VecDeque::from([0x80, 0x80, 0x00]),
        ..MockController::default()
    };
    let (result, mock) = programmed(mock);
    result.unwrap();
    let order: Vec<(u16, bool)> = mock.commands.iter().map(|c| (c.0, c.1)).collect();
    let w = |c: protocol::Command| (c.code, false);
    let r = |c: protocol::Command| (c.code, true);
    assert_eq!(
        order,
        vec![
            w(protocol::PATTERN_START_STOP),
            w(protocol::DISPLAY_MODE),
            w(protocol::PATTERN_SOURCE),
            w(protocol::PATTERN_TRIGGER_MODE),
            w(protocol::EXPOSURE_PERIOD),
            w(protocol::TRIGGER_OUT1),
            w(protocol::MAILBOX_CONTROL),
            w(protocol::MAILBOX_ADDRESS),
            w(protocol::MAILBOX_DATA),
            w(protocol::MAILBOX_CONTROL),
            w(protocol::PATTERN_CONFIG),
            w(protocol::VALIDATE),
            r(protocol::VALIDATE),
            r(protocol::VALIDATE),
            r(protocol::VALIDATE),
            w(protocol::PATTERN_START_STOP),
        ]
    );
    // Sequence numbers count up; the data are the plan's: stop, pattern mode, video input,
    // VSYNC trigger, 2500/2500 µs, open LUT mailbox, 27 LUT bytes, close, 9 entries repeated,
    // start.
    let sequences: Vec<u8> = mock.commands.iter().map(|c| c.2).collect();
    assert_eq!(sequences, (0..16).collect::<Vec<u8>>());
    let data: Vec<&[u8]> = mock.commands.iter().map(|c| c.3.as_slice()).collect();
    assert_eq!(data[0], [0]);
    assert_eq!(data[1], [1]);
    assert_eq!(data[2], [0]);
    assert_eq!(data[3], [0]);
    assert_eq!(data[4], [0xC4, 0x09, 0, 0, 0xC4, 0x09, 0, 0]);
    assert_eq!(data[6], [2]);
    assert_eq!(data[8].len(), 27);
    assert_eq!(data[9], [0]);
    assert_eq!(data[10], [8, 1, 8, 0]);
    assert_eq!(data[15], [2]);
    assert!(mock.validation.is_empty());
}

#[test]
fn a_nack_or_a_failed_validation_stops_before_the_sequence_starts() {
    let (result, mock) = programmed(MockController {
        nack: Some(protocol::EXPOSURE_PERIOD.code),
        ..MockController::default()
    });
    match result {
        Err(LightcrafterError::Nack(name)) => assert_eq!(name, protocol::EXPOSURE_PERIOD.name),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        mock.commands.last().unwrap().0,
        protocol::EXPOSURE_PERIOD.code
    );

    let (result, mock) = programmed(MockController {
        validation: VecDeque::from([0x80, 0x02]),
        ..MockController::default()
    });
    match result {
        Err(e @ LightcrafterError::ValidationFailed(_)) => {
            assert!(
                e.to_string()
                    .contains("pattern numbers in the LUT are invalid"),
                "{e}"
            )
        }
        other => panic!("{other:?}"),
    }
    let starts = mock
        .commands
        .iter()
        .filter(|c| c.0 == protocol::PATTERN_START_STOP.code && c.3 == [2])
        .count();
    assert_eq!(starts, 0, "a rejected sequence must not start");

    // Warnings alone: the sequence starts and the warnings are kept for the status bar.
    let mut lc = LightCrafter::new(MockController {
        validation: VecDeque::from([0x10]),
        ..MockController::default()
    });
    lc.program_cps(&CpsTiming::new(121.0, 6).unwrap()).unwrap();
    assert_eq!(lc.warnings.len(), 1);
}

#[test]
fn the_projector_refuses_sequences_other_than_cps_rgb_and_programs_cps_rgb() {
    use tremorscan::pattern::{cps_gray, cps_rgb, Axis, CpsGrayVariant};
    let mut lc = LightCrafter::new(MockController {
        validation: VecDeque::from([0x00]),
        ..MockController::default()
    });
    let gray = cps_gray(65, CpsGrayVariant::Minimal7, 912.0, Axis::Columns, 8).unwrap();
    let err = lc.show(&gray).unwrap_err();
    assert!(err.to_string().contains("3 RGB images"), "{err}");
    assert!(lc.into_transport().commands.is_empty());

    let mut lc = LightCrafter::new(MockController {
        validation: VecDeque::from([0x00]),
        ..MockController::default()
    });
    lc.show(&cps_rgb(65, 912.0, Axis::Columns, 8).unwrap())
        .unwrap();
    let mock = lc.into_transport();
    // 121 FPS: 6-bit patterns of 2500 µs.
    let exposure = mock
        .commands
        .iter()
        .find(|c| c.0 == protocol::EXPOSURE_PERIOD.code)
        .unwrap();
    assert_eq!(exposure.3[..4], 2500u32.to_le_bytes());
}

/// Without a LightCrafter on the bus (this machine, CI), opening is a clear error, never a panic.
#[cfg(feature = "lightcrafter")]
#[test]
fn opening_without_a_device_is_a_clear_error() {
    match tremorscan::device::lightcrafter::usb::open() {
        Err(LightcrafterError::Absent) => {}
        // A machine without a USB subsystem at all (a container) reports libusb's error.
        Err(LightcrafterError::Usb(why)) => assert!(!why.is_empty()),
        Err(e) => panic!("unexpected error: {e}"),
        Ok(_) => eprintln!("a LightCrafter is connected; nothing to check here"),
    }
}
