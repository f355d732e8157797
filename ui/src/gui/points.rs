//! Control points on screen: their colours (red, green, blue first, as in the paper's
//! Figure 2, then further distinct colours), the list where they are renamed and removed, and the
//! edits the views ask for, applied to the tracker in one place.

use egui::Color32;
use std::collections::BTreeMap;
use tremorscan::tremor::{LiveTracker, PointMode};

const PALETTE: [Color32; 10] = [
    Color32::from_rgb(230, 40, 40),
    Color32::from_rgb(40, 200, 60),
    Color32::from_rgb(50, 110, 255),
    Color32::from_rgb(255, 160, 0),
    Color32::from_rgb(200, 60, 220),
    Color32::from_rgb(0, 200, 210),
    Color32::from_rgb(240, 220, 40),
    Color32::from_rgb(150, 90, 40),
    Color32::from_rgb(255, 120, 170),
    Color32::from_rgb(140, 140, 140),
];

/// An edit of the control points, asked for by a view or the list.
#[derive(Debug, Clone, PartialEq)]
pub enum PointEdit {
    Add {
        pixel: (f64, f64),
    },
    Move {
        id: u64,
        pixel: (f64, f64),
    },
    Rename {
        id: u64,
        name: String,
    },
    Remove {
        id: u64,
    },
    /// Follow the skin or keep fixed pixels (every point starts anew).
    Mode(PointMode),
}

/// Each point's colour slot, kept when other points are removed.
#[derive(Debug, Default, Clone)]
pub struct PointColours {
    slots: BTreeMap<u64, usize>,
}

impl PointColours {
    pub fn colour(&mut self, id: u64) -> Color32 {
        let slot = match self.slots.get(&id) {
            Some(&slot) => slot,
            None => {
                let slot = (0..)
                    .find(|s| !self.slots.values().any(|v| v == s))
                    .unwrap_or(0);
                self.slots.insert(id, slot);
                slot
            }
        };
        let base = PALETTE[slot % PALETTE.len()];
        if slot < PALETTE.len() {
            base
        } else {
            // Beyond the palette: the same hues, darker, so they stay distinguishable.
            Color32::from_rgb(base.r() / 2, base.g() / 2, base.b() / 2)
        }
    }

    pub fn forget(&mut self, id: u64) {
        self.slots.remove(&id);
    }
}

/// Applies `edit` to `tracker`; returns the new point's id for an addition.
pub fn apply(
    tracker: &mut LiveTracker,
    colours: &mut PointColours,
    edit: PointEdit,
) -> Option<u64> {
    match edit {
        PointEdit::Add { pixel } => {
            let name = format!("P{}", tracker.points.len() + 1);
            let id = tracker.add(name, pixel);
            colours.colour(id);
            Some(id)
        }
        PointEdit::Move { id, pixel } => {
            tracker.move_to(id, pixel);
            None
        }
        PointEdit::Rename { id, name } => {
            tracker.rename(id, name);
            None
        }
        PointEdit::Remove { id } => {
            tracker.remove(id);
            colours.forget(id);
            None
        }
        PointEdit::Mode(mode) => {
            tracker.set_mode(mode);
            None
        }
    }
}

/// A control point's marker: a ring in its colour with its name beside it.
pub fn draw_marker(painter: &egui::Painter, centre: egui::Pos2, colour: Color32, name: &str) {
    painter.circle_stroke(centre, 6.5, egui::Stroke::new(2.0, colour));
    painter.text(
        centre + egui::vec2(8.0, -8.0),
        egui::Align2::LEFT_BOTTOM,
        name,
        egui::FontId::proportional(13.0),
        colour,
    );
}

/// The list of points: colour, editable name, pixel, latest depth, remove button.
pub fn points_list_ui(
    ui: &mut egui::Ui,
    tracker: &LiveTracker,
    colours: &mut PointColours,
    edits: &mut Vec<PointEdit>,
) {
    ui.heading("Control points");
    let mut follow = tracker.mode() == PointMode::FollowSkin;
    if ui
        .checkbox(&mut follow, "Follow the skin")
        .on_hover_text(
            "On: each point follows the patch of skin it was placed on. \
             Off: each point stays at its camera pixel and measures whatever surface passes it.",
        )
        .changed()
    {
        edits.push(PointEdit::Mode(if follow {
            PointMode::FollowSkin
        } else {
            PointMode::FixedPixel
        }));
    }
    if tracker.points.is_empty() {
        ui.label("Click the hand in the camera image or the 3D view to add a point.");
        return;
    }
    egui::Grid::new("control_points")
        .num_columns(4)
        .striped(true)
        .show(ui, |ui| {
            for (k, p) in tracker.points.iter().enumerate() {
                let colour = colours.colour(p.id);
                let tag =
                    ui.colored_label(colour, egui::RichText::new(format!("#{}", k + 1)).strong());
                let mut name = p.name.clone();
                let edit = ui
                    .add(
                        egui::TextEdit::singleline(&mut name)
                            .desired_width(90.0)
                            .id_salt(("point_name", p.id)),
                    )
                    .labelled_by(tag.id);
                if edit.changed() {
                    edits.push(PointEdit::Rename { id: p.id, name });
                }
                let depth = p
                    .latest_position_mm()
                    .map_or("—".to_string(), |q| format!("z {:.1} mm", q[2]));
                let (u, v) = p.current_pixel();
                match p.follow_error() {
                    Some(why) => ui
                        .colored_label(Color32::from_rgb(230, 160, 40), "no texture to follow")
                        .on_hover_text(why),
                    None => ui.label(format!("({u:.0}, {v:.0}) {depth}")),
                };
                if ui
                    .button("Remove")
                    .on_hover_text(format!("Remove {}", p.name))
                    .clicked()
                {
                    edits.push(PointEdit::Remove { id: p.id });
                }
                ui.end_row();
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_three_points_are_red_green_blue_and_colours_survive_removals() {
        let mut c = PointColours::default();
        assert_eq!(c.colour(1), PALETTE[0]);
        assert_eq!(c.colour(2), PALETTE[1]);
        assert_eq!(c.colour(3), PALETTE[2]);
        c.forget(1);
        assert_eq!(c.colour(3), PALETTE[2]);
        // The freed red goes to the next new point.
        assert_eq!(c.colour(4), PALETTE[0]);
        for id in 5..20 {
            c.colour(id);
        }
        assert_ne!(c.colour(14), c.colour(4));
    }
}
