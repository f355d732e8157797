//! Camera frames: 8-bit images with their capture time and the pattern they show.

/// Errors about frame buffers.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FrameError {
    #[error(
        "frame is {got_width}×{got_height}×{got_channels}, expected {width}×{height}×{channels}"
    )]
    WrongShape {
        width: usize,
        height: usize,
        channels: usize,
        got_width: usize,
        got_height: usize,
        got_channels: usize,
    },
    #[error("frame buffer holds {got} bytes, {width}×{height}×{channels} needs {expected}")]
    WrongLength {
        width: usize,
        height: usize,
        channels: usize,
        expected: usize,
        got: usize,
    },
    #[error("a frame needs 1 (gray) or 3 (RGB) channels, got {0}")]
    BadChannels(usize),
}

/// An 8-bit camera frame, interleaved when `channels == 3` (R, G, B).
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<u8>,
    /// Capture time of the middle of the exposure, seconds since the stream started.
    pub time_s: f64,
    /// Which entry of the pattern sequence the frame shows.
    pub pattern_index: usize,
}

impl Frame {
    /// A 0×0 RGB frame, to be filled (grabs and copies resize it).
    pub fn empty() -> Self {
        Self {
            width: 0,
            height: 0,
            channels: 3,
            data: Vec::new(),
            time_s: 0.0,
            pattern_index: 0,
        }
    }

    /// A black frame.
    pub fn new(width: usize, height: usize, channels: usize) -> Result<Self, FrameError> {
        if channels != 1 && channels != 3 {
            return Err(FrameError::BadChannels(channels));
        }
        Ok(Self {
            width,
            height,
            channels,
            data: vec![0; width * height * channels],
            time_s: 0.0,
            pattern_index: 0,
        })
    }

    /// Wraps an existing buffer, checking its length.
    pub fn from_data(
        width: usize,
        height: usize,
        channels: usize,
        data: Vec<u8>,
    ) -> Result<Self, FrameError> {
        if channels != 1 && channels != 3 {
            return Err(FrameError::BadChannels(channels));
        }
        let expected = width * height * channels;
        if data.len() != expected {
            return Err(FrameError::WrongLength {
                width,
                height,
                channels,
                expected,
                got: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
            time_s: 0.0,
            pattern_index: 0,
        })
    }

    /// Checks that the frame has the given shape.
    pub fn check_shape(
        &self,
        width: usize,
        height: usize,
        channels: usize,
    ) -> Result<(), FrameError> {
        if self.width != width || self.height != height || self.channels != channels {
            return Err(FrameError::WrongShape {
                width,
                height,
                channels,
                got_width: self.width,
                got_height: self.height,
                got_channels: self.channels,
            });
        }
        if self.data.len() != width * height * channels {
            return Err(FrameError::WrongLength {
                width,
                height,
                channels,
                expected: width * height * channels,
                got: self.data.len(),
            });
        }
        Ok(())
    }

    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_checks_name_the_problem() {
        assert_eq!(Frame::new(2, 2, 2), Err(FrameError::BadChannels(2)));
        let err = Frame::from_data(4, 4, 3, vec![0; 10]).unwrap_err();
        assert!(err.to_string().contains("needs 48"));
        let f = Frame::new(4, 3, 3).unwrap();
        assert!(f.check_shape(4, 3, 3).is_ok());
        let err = f.check_shape(4, 4, 3).unwrap_err();
        assert!(err.to_string().contains("expected 4×4×3"), "{err}");
    }
}
