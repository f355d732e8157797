//! The second screen as the projector: a borderless fullscreen viewport on the chosen monitor
//! that shows the pattern sequence and records what it showed when.
//!
//! Every pass of the viewport is one refresh of the screen. The current image stays for
//! `hold_refreshes` passes, then the next one follows; each change is pushed to the shared
//! [`PatternSchedule`] with the host time it was handed to the display, which the camera side
//! ([`SyncedCamera`](tremorscan::device::synced_camera::SyncedCamera)) reads to label frames. Two
//! modes: the flash code (black/white, to measure the delay) and the patterns themselves.
//!
//! Where the backend cannot open a second window (tests), egui embeds the viewport as a window.

use std::sync::{Arc, Mutex, PoisonError};
use tremorscan::device::lightcrafter::timing::pack_video_pixel;
use tremorscan::device::screen_sync::{flash_code, host_time_s, PatternSchedule, Shown};
use tremorscan::pattern::{render_pattern, PatternSequence};

/// Elements of the flash code: at 2 refreshes each on a 60 Hz screen, 4 s.
pub const FLASH_ELEMENTS: usize = 120;

/// What the screen shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScreenMode {
    /// The black/white flash code; element `next` comes next.
    Flash { next: usize },
    /// The pattern sequence; entry `next` comes next.
    Patterns { next: usize },
}

pub struct ProjectorScreen {
    pub monitor: usize,
    pub hold_refreshes: u32,
    pub mode: ScreenMode,
    pub schedule: Arc<Mutex<PatternSchedule>>,
    /// Pattern images at the projector's resolution, RGB.
    images: Vec<egui::ColorImage>,
    textures: Vec<egui::TextureHandle>,
    black: Option<egui::TextureHandle>,
    white: Option<egui::TextureHandle>,
    code: Vec<bool>,
    refreshes_left: u32,
    /// What is on screen now: texture and pattern index.
    current: Option<(ShownTexture, usize)>,
    /// Host times of the last pattern changes, for the achieved pattern rate.
    changes: std::collections::VecDeque<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ShownTexture {
    Black,
    White,
    Pattern(usize),
}

impl ProjectorScreen {
    /// A screen on `monitor` (winit's order) for `sequence` at `size` pixels, starting with the
    /// flash code. With `packed_bits` the images are packed for a LightCrafter's video input
    /// (three channels of that many bits in the 24 bit planes, see `pack_video_pixel`).
    pub fn new(
        sequence: &PatternSequence,
        size: (usize, usize),
        monitor: usize,
        hold_refreshes: u32,
        packed_bits: Option<u8>,
    ) -> anyhow::Result<Self> {
        let images = (0..sequence.entries.len())
            .map(|i| {
                let p = render_pattern(sequence, i, size.0, size.1)?;
                let mut rgb: Vec<u8> = if p.channels == 3 {
                    p.data
                } else {
                    p.data.iter().flat_map(|&v| [v, v, v]).collect()
                };
                if let Some(bits) = packed_bits {
                    for px in rgb.chunks_exact_mut(3) {
                        px.copy_from_slice(&pack_video_pixel([px[0], px[1], px[2]], bits));
                    }
                }
                Ok(egui::ColorImage::from_rgb([p.width, p.height], &rgb))
            })
            .collect::<Result<Vec<_>, tremorscan::pattern::PatternError>>()?;
        Ok(Self {
            monitor,
            hold_refreshes: hold_refreshes.max(1),
            mode: ScreenMode::Flash { next: 0 },
            schedule: Arc::default(),
            images,
            textures: Vec::new(),
            black: None,
            white: None,
            code: flash_code(FLASH_ELEMENTS),
            refreshes_left: 0,
            current: None,
            changes: std::collections::VecDeque::new(),
        })
    }

    /// Whether the flash code has been shown to its end.
    pub fn flash_done(&self) -> bool {
        matches!(self.mode, ScreenMode::Flash { next } if next >= self.code.len())
            && self.refreshes_left == 0
    }

    /// Switches to the pattern sequence.
    pub fn show_patterns(&mut self) {
        self.mode = ScreenMode::Patterns { next: 0 };
        self.refreshes_left = 0;
    }

    /// Pattern changes per second over the last second.
    pub fn pattern_rate_hz(&self) -> f64 {
        match (self.changes.front(), self.changes.back()) {
            (Some(a), Some(b)) if b > a => (self.changes.len() - 1) as f64 / (b - a),
            _ => 0.0,
        }
    }

    fn upload(&mut self, ctx: &egui::Context) {
        if !self.textures.is_empty() {
            return;
        }
        let options = egui::TextureOptions::NEAREST;
        self.textures = self
            .images
            .iter()
            .enumerate()
            .map(|(i, img)| {
                ctx.load_texture(format!("projector-pattern-{i}"), img.clone(), options)
            })
            .collect();
        let [w, h] = self.images.first().map_or([1, 1], |i| i.size);
        let flat = |v: u8| egui::ColorImage::new([w, h], vec![egui::Color32::from_gray(v); w * h]);
        self.black = Some(ctx.load_texture("projector-black", flat(0), options));
        self.white = Some(ctx.load_texture("projector-white", flat(255), options));
    }

    /// Advances one refresh: the next image when the current one has been held long enough.
    fn advance(&mut self) {
        if self.refreshes_left > 0 {
            self.refreshes_left -= 1;
            return;
        }
        let next = match &mut self.mode {
            ScreenMode::Flash { next } => {
                let Some(&white) = self.code.get(*next) else {
                    return;
                };
                *next += 1;
                let texture = if white {
                    ShownTexture::White
                } else {
                    ShownTexture::Black
                };
                (texture, usize::MAX, if white { 1.0 } else { 0.0 })
            }
            ScreenMode::Patterns { next } => {
                let count = self.images.len().max(1);
                let index = *next % count;
                *next = (index + 1) % count;
                (ShownTexture::Pattern(index), index, 0.5)
            }
        };
        self.refreshes_left = self.hold_refreshes - 1;
        self.current = Some((next.0, next.1));
        let now = host_time_s();
        self.schedule
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(Shown {
                pattern_index: next.1,
                level: next.2,
                from_s: now,
            });
        self.changes.push_back(now);
        while self.changes.front().is_some_and(|&t| t < now - 1.0) {
            self.changes.pop_front();
        }
    }

    /// Shows the screen's viewport for this pass (call every pass while it is in use).
    pub fn viewport_ui(&mut self, ctx: &egui::Context) {
        self.upload(ctx);
        let builder = egui::ViewportBuilder::default()
            .with_title("tremorscan projector")
            .with_decorations(false)
            .with_monitor(self.monitor)
            .with_fullscreen(true);
        ctx.show_viewport_immediate(
            egui::ViewportId::from_hash_of("tremorscan-projector"),
            builder,
            |ui, _class| {
                self.advance();
                let texture = match self.current.map(|c| c.0) {
                    Some(ShownTexture::White) => self.white.as_ref(),
                    Some(ShownTexture::Pattern(i)) => self.textures.get(i),
                    Some(ShownTexture::Black) | None => self.black.as_ref(),
                };
                let rect = ui.max_rect();
                if let Some(texture) = texture {
                    ui.painter().image(
                        texture.id(),
                        rect,
                        egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                        egui::Color32::WHITE,
                    );
                }
                // The screen changes every refresh.
                ui.ctx().request_repaint();
            },
        );
    }
}
