//! The viewer's controls and image area (egui, immediate mode): the side
//! panel of methods, views, light and camera; the image with its split
//! divider, orbit and light drags; the overlay of pass times, work
//! counters, memory and error; the magnifier's sample dots.

use super::images::{frame_layout, mean_abs_error, view_notice};
use super::state::{ViewKind, ViewState, IZB_METHODS, MAP_FAMILIES, MAP_SIDES, OTHER_METHODS};
use super::worker::FrameResult;
use crate::scene::{Light, Scene};
use egui::{Color32, Pos2, Rect, Sense, Stroke, Vec2};

/// The frame on screen and its textures (one per method, in the view
/// they were built for).
pub struct Shown {
    pub result: FrameResult,
    pub textures: Vec<egui::TextureHandle>,
    /// The textures' pixels (the magnifier paints them as cells: the
    /// UI renderer samples textures bilinearly).
    pub pixels: Vec<Vec<[u8; 4]>>,
    /// (view, truth samples) the textures show.
    pub texture_key: (ViewKind, u32),
}

/// What the overlay reports besides the frame.
pub struct Status<'a> {
    /// Seconds the current frame has been computing, if it is.
    pub computing: Option<f64>,
    /// The progressive truth of the current view and its samples per pixel.
    pub truth: Option<(&'a [f32], u32)>,
    /// Messages for the window (errors, fallbacks).
    pub messages: &'a [String],
    pub compute_device: String,
    pub present_device: &'a str,
    /// The last UI frame's milliseconds.
    pub ui_millis: f64,
}

/// Requests from the controls.
#[derive(Default)]
pub struct UiRequests {
    pub screenshot: bool,
    /// Where the image lies in the window, in physical pixels
    /// (x0, y0, x1, y1): screenshots record it.
    pub image_rect_px: Option<[f32; 4]>,
}

/// Draws the whole window.
pub fn draw(
    root: &mut egui::Ui,
    state: &mut ViewState,
    base: &Scene,
    shown: Option<&Shown>,
    status: &Status,
    magnify: &mut Option<[u32; 2]>,
) -> UiRequests {
    let mut requests = UiRequests::default();
    egui::Panel::left("controls")
        .resizable(false)
        .default_size(230.0)
        .show(root, |ui| controls(ui, state, base, &mut requests));
    egui::CentralPanel::default()
        .frame(egui::Frame::NONE.fill(Color32::from_gray(20)))
        .show(root, |ui| {
            let rect = image_area(ui, state, shown, status, magnify);
            let scale = ui.ctx().pixels_per_point();
            requests.image_rect_px =
                rect.map(|r| [r.min.x, r.min.y, r.max.x, r.max.y].map(|v| v * scale));
        });
    // Keys belong to a text field while one has focus.
    if root.ctx().egui_wants_keyboard_input() {
        return requests;
    }
    root.ctx().input(|i| {
        if i.key_pressed(egui::Key::S) {
            requests.screenshot = true;
        }
        let step = 5.0;
        if i.key_pressed(egui::Key::ArrowLeft) {
            state.light_turn[0] -= step;
        }
        if i.key_pressed(egui::Key::ArrowRight) {
            state.light_turn[0] += step;
        }
        if i.key_pressed(egui::Key::ArrowUp) {
            state.light_turn[1] += step;
        }
        if i.key_pressed(egui::Key::ArrowDown) {
            state.light_turn[1] -= step;
        }
    });
    requests
}

fn method_picker(ui: &mut egui::Ui, id: &str, method: &mut String) {
    let (mut family, mut side) = match method.rsplit_once('-') {
        Some((f, s)) if MAP_FAMILIES.contains(&f) => (f.to_string(), s.parse().unwrap_or(2048)),
        _ => (method.clone(), 2048u32),
    };
    egui::ComboBox::from_id_salt(id)
        .selected_text(family.as_str())
        .show_ui(ui, |ui| {
            for name in IZB_METHODS
                .iter()
                .chain(&MAP_FAMILIES)
                .chain(&OTHER_METHODS)
            {
                ui.selectable_value(&mut family, name.to_string(), *name);
            }
        });
    if MAP_FAMILIES.contains(&family.as_str()) {
        egui::ComboBox::from_id_salt(format!("{id}-side"))
            .selected_text(format!("{side}²"))
            .show_ui(ui, |ui| {
                for s in MAP_SIDES {
                    ui.selectable_value(&mut side, s, format!("{s}²"));
                }
            });
        *method = format!("{family}-{side}");
    } else {
        *method = family;
    }
}

fn controls(ui: &mut egui::Ui, state: &mut ViewState, base: &Scene, requests: &mut UiRequests) {
    ui.heading("izb view");
    ui.label(format!(
        "{} · {}×{} · {} triangles",
        base.name,
        base.resolution[0],
        base.resolution[1],
        base.triangles.len()
    ));
    ui.separator();
    ui.label("Method");
    method_picker(ui, "method", &mut state.method);
    let mut split = state.split.is_some();
    ui.checkbox(&mut split, "Split screen: second method");
    if split {
        let mut right = state.split.clone().unwrap_or_else(|| "pcf3-2048".into());
        method_picker(ui, "split", &mut right);
        state.split = Some(right);
        ui.add(egui::Slider::new(&mut state.divider, 0.0..=1.0).text("divider"));
    } else {
        state.split = None;
    }
    ui.separator();
    ui.label("View");
    for v in ViewKind::ALL {
        ui.radio_value(&mut state.view, v, v.name());
    }
    ui.separator();
    ui.label("Light (right-drag, arrow keys)");
    ui.add(
        egui::DragValue::new(&mut state.light_turn[0])
            .suffix("° turn")
            .speed(0.5),
    );
    ui.add(
        egui::DragValue::new(&mut state.light_turn[1])
            .suffix("° up")
            .speed(0.5),
    );
    let unit = match base.light {
        Light::Directional { .. } => "° radius",
        Light::Point { .. } => " radius",
    };
    let top = state.light_size_top;
    ui.add(
        egui::Slider::new(&mut state.light_size, 0.0..=top)
            .text(unit)
            .clamping(egui::SliderClamping::Never),
    );
    ui.separator();
    ui.label("Camera (drag, scroll)");
    ui.add(
        egui::DragValue::new(&mut state.orbit[0])
            .suffix("° orbit")
            .speed(0.5),
    );
    ui.add(
        egui::DragValue::new(&mut state.orbit[1])
            .suffix("° up")
            .speed(0.5),
    );
    ui.add(
        egui::Slider::new(&mut state.orbit[2], 0.2..=5.0)
            .logarithmic(true)
            .text("distance"),
    );
    if ui.button("Reset camera and light").clicked() {
        let fresh = ViewState::new(base);
        state.orbit = fresh.orbit;
        state.light_turn = fresh.light_turn;
        state.light_size = fresh.light_size;
    }
    ui.separator();
    ui.checkbox(&mut state.overlay, "Overlay: times, work, error");
    if ui.button("Screenshot (S)").clicked() {
        requests.screenshot = true;
    }
}

/// The largest rectangle of `aspect` centred in `area`.
fn fit(area: Rect, aspect: f32) -> Rect {
    let size = if area.width() / area.height() > aspect {
        Vec2::new(area.height() * aspect, area.height())
    } else {
        Vec2::new(area.width(), area.width() / aspect)
    };
    Rect::from_center_size(area.center(), size)
}

fn image_area(
    ui: &mut egui::Ui,
    state: &mut ViewState,
    shown: Option<&Shown>,
    status: &Status,
    magnify: &mut Option<[u32; 2]>,
) -> Option<Rect> {
    let area = ui.available_rect_before_wrap();
    let response = ui.allocate_rect(area, Sense::click_and_drag());
    let painter = ui.painter_at(area);
    let Some(shown) = shown else {
        painter.text(
            area.center(),
            egui::Align2::CENTER_CENTER,
            "computing the first frame…",
            egui::FontId::proportional(18.0),
            Color32::LIGHT_GRAY,
        );
        if state.overlay {
            overlay(ui, area, None, status);
        }
        return None;
    };
    let [w, h] = shown.result.scene.resolution;
    let rect = fit(area, w as f32 / h as f32);
    let full = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
    let divider_x = rect.left() + state.divider * rect.width();
    match shown.textures.as_slice() {
        [left, right, ..] => {
            let d = state.divider;
            let left_rect = Rect::from_min_max(rect.min, Pos2::new(divider_x, rect.max.y));
            let right_rect = Rect::from_min_max(Pos2::new(divider_x, rect.min.y), rect.max);
            let uv = |x0: f32, x1: f32| Rect::from_min_max(Pos2::new(x0, 0.0), Pos2::new(x1, 1.0));
            painter.image(left.id(), left_rect, uv(0.0, d), Color32::WHITE);
            painter.image(right.id(), right_rect, uv(d, 1.0), Color32::WHITE);
            painter.line_segment(
                [
                    Pos2::new(divider_x, rect.top()),
                    Pos2::new(divider_x, rect.bottom()),
                ],
                Stroke::new(2.0, Color32::WHITE),
            );
        }
        [only] => {
            painter.image(only.id(), rect, full, Color32::WHITE);
        }
        [] => {}
    }
    let has_candidates = shown.result.candidates.is_some();
    if let Some(notice) = view_notice(state.view, has_candidates, status.truth.is_some()) {
        painter.text(
            rect.center(),
            egui::Align2::CENTER_CENTER,
            notice,
            egui::FontId::proportional(16.0),
            Color32::LIGHT_GRAY,
        );
    }
    // Drags: the divider when grabbed near it, else orbit (left button)
    // or light (right button or shift); scroll zooms.
    let near_divider = |p: Pos2| (p.x - divider_x).abs() < 8.0 && shown.textures.len() > 1;
    if response.dragged() {
        let delta = response.drag_delta();
        let origin = ui.input(|i| i.pointer.press_origin());
        if origin.is_some_and(near_divider) {
            if let Some(p) = response.interact_pointer_pos() {
                state.divider = ((p.x - rect.left()) / rect.width()).clamp(0.0, 1.0);
            }
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || ui.input(|i| i.modifiers.shift)
        {
            state.light_turn[0] += f64::from(delta.x) * 0.3;
            state.light_turn[1] -= f64::from(delta.y) * 0.3;
        } else {
            state.orbit[0] -= f64::from(delta.x) * 0.3;
            state.orbit[1] += f64::from(delta.y) * 0.3;
        }
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            state.orbit[2] = (state.orbit[2] * f64::from(-scroll * 0.002).exp()).clamp(0.05, 20.0);
        }
        // Only a moving pointer moves the magnifier (a script places it).
        let moved = ui.input(|i| i.pointer.delta() != Vec2::ZERO);
        if let Some(p) = response.hover_pos().filter(|_| moved) {
            if rect.contains(p) {
                let x = ((p.x - rect.left()) / rect.width() * w as f32) as u32;
                let y = ((p.y - rect.top()) / rect.height() * h as f32) as u32;
                *magnify = Some([x.min(w - 1), y.min(h - 1)]);
            }
        }
    }
    if let Some(px) = *magnify {
        magnifier(ui, area, rect, state, shown, px);
    }
    if state.overlay {
        overlay(ui, area, Some(shown), status);
    }
    Some(rect)
}

/// The per-method report in the image's top-left corner.
fn overlay(ui: &mut egui::Ui, area: Rect, shown: Option<&Shown>, status: &Status) {
    egui::Area::new(egui::Id::new("overlay"))
        .fixed_pos(area.min + Vec2::new(8.0, 8.0))
        .interactable(false)
        .show(ui.ctx(), |ui| {
            egui::Frame::popup(ui.style())
                .fill(Color32::from_black_alpha(190))
                .show(ui, |ui| {
                    ui.label(format!("compute: {}", status.compute_device));
                    ui.label(format!(
                        "window: {} · UI frame {:.1} ms",
                        status.present_device, status.ui_millis
                    ));
                    if let Some(s) = status.computing {
                        ui.colored_label(
                            Color32::YELLOW,
                            format!("computing the new frame… {s:.1} s"),
                        );
                    }
                    match status.truth {
                        Some((_, spp)) => ui.label(format!("truth: {spp} spp (ray traced, f64)")),
                        None => ui.label("truth: waits for a still view"),
                    };
                    if let Some(shown) = shown {
                        for f in &shown.result.frames {
                            ui.separator();
                            ui.strong(&f.name);
                            ui.label(&f.backend);
                            let passes: Vec<String> = f
                                .pass_millis
                                .iter()
                                .map(|(n, ms)| format!("{n} {ms:.2}"))
                                .collect();
                            ui.label(format!("ms: {}", passes.join(" · ")));
                            let mut line =
                                format!("memory {:.1} MiB", f.memory_bytes as f64 / 1048576.0);
                            if let Some(t) = f.tests_per_pixel {
                                line += &format!(" · {t:.1} tests/pixel");
                            }
                            ui.label(line);
                            if let Some((truth, spp)) = status.truth {
                                if let Some((mae, _)) = mean_abs_error(&f.visibility, truth) {
                                    ui.label(format!("MAE {mae:.4} against {spp} spp"));
                                }
                            }
                        }
                        for e in &shown.result.errors {
                            ui.colored_label(Color32::LIGHT_RED, e);
                        }
                    }
                    for m in status.messages {
                        ui.colored_label(Color32::LIGHT_RED, m);
                    }
                });
        });
}

/// A zoomed crop around pixel `px` and its mask as sample dots (red:
/// occluded, yellow: lit), for the method under that pixel's side of the
/// divider.
fn magnifier(
    ui: &mut egui::Ui,
    area: Rect,
    rect: Rect,
    state: &ViewState,
    shown: &Shown,
    px: [u32; 2],
) {
    let w = shown.result.scene.resolution[0];
    let side = if shown.textures.len() > 1 && px[0] as f32 >= state.divider * w as f32 {
        1
    } else {
        0
    };
    let (Some(frame), Some(pixels)) = (shown.result.frames.get(side), shown.pixels.get(side))
    else {
        return;
    };
    let box_size = 150.0;
    let origin = Pos2::new(area.right() - 2.0 * box_size - 24.0, area.top() + 8.0);
    let crop = Rect::from_min_size(origin, Vec2::splat(box_size));
    let dots = Rect::from_min_size(
        origin + Vec2::new(box_size + 8.0, 0.0),
        Vec2::splat(box_size),
    );
    // An area of its own, above the image and the overlay.
    egui::Area::new(egui::Id::new("magnifier"))
        .order(egui::Order::Foreground)
        .fixed_pos(crop.min)
        .interactable(false)
        .show(ui.ctx(), |ui| {
            ui.allocate_space(crop.union(dots).size());
            paint_magnifier(ui.painter(), [crop, dots, rect], shown, frame, pixels, px);
        });
}

/// The magnifier's contents: `crop` (pixels as cells), `dots` (the mask's
/// samples) and a marker on `image`.
fn paint_magnifier(
    painter: &egui::Painter,
    [crop, dots, rect]: [Rect; 3],
    shown: &Shown,
    frame: &super::worker::MethodFrame,
    pixels: &[[u8; 4]],
    px: [u32; 2],
) {
    let [w, h] = shown.result.scene.resolution;
    let i = (px[1] * w + px[0]) as usize;
    let radius = 7i32;
    let box_size = crop.width();
    painter.rect_filled(
        crop.union(dots).expand(6.0),
        4.0,
        Color32::from_black_alpha(200),
    );
    // The crop: one cell per image pixel, (2 radius + 1)² of them.
    let cell = box_size / (2 * radius + 1) as f32;
    for dy in -radius..=radius {
        for dx in -radius..=radius {
            let (x, y) = (px[0] as i32 + dx, px[1] as i32 + dy);
            if x < 0 || y < 0 || x >= w as i32 || y >= h as i32 {
                continue;
            }
            let [r, g, b, _] = pixels[(y as u32 * w + x as u32) as usize];
            let min = crop.min + Vec2::new((dx + radius) as f32, (dy + radius) as f32) * cell;
            painter.rect_filled(
                Rect::from_min_size(min, Vec2::splat(cell)),
                0.0,
                Color32::from_rgb(r, g, b),
            );
        }
    }
    painter.rect_stroke(
        Rect::from_center_size(crop.center(), Vec2::splat(cell)),
        0.0,
        Stroke::new(1.5, Color32::LIGHT_BLUE),
        egui::StrokeKind::Outside,
    );
    let marker = rect.min
        + Vec2::new(
            (px[0] as f32 + 0.5) / w as f32 * rect.width(),
            (px[1] as f32 + 0.5) / h as f32 * rect.height(),
        );
    painter.circle_stroke(marker, 6.0, Stroke::new(1.5, Color32::LIGHT_BLUE));
    let v = frame.visibility.get(i).copied().unwrap_or(f32::NAN);
    let mut text = format!("pixel ({}, {}) · {}: lit {v:.3}", px[0], px[1], frame.name);
    match frame_layout(frame, &shown.result.scene) {
        Some(layout) if !frame.masks.is_empty() => {
            let mask = u64::from(frame.masks[i])
                | (u64::from(frame.masks_high.get(i).copied().unwrap_or(0)) << 32);
            if layout.on_light_disk {
                painter.circle_stroke(
                    dots.center(),
                    box_size / 2.0,
                    Stroke::new(1.0, Color32::GRAY),
                );
            } else {
                painter.rect_stroke(
                    dots,
                    0.0,
                    Stroke::new(1.0, Color32::GRAY),
                    egui::StrokeKind::Inside,
                );
            }
            for (bit, p) in layout.points.iter().enumerate() {
                let pos = dots.min + Vec2::new(p[0], p[1]) * box_size;
                let occluded = mask >> bit & 1 == 1;
                let colour = if occluded {
                    Color32::from_rgb(230, 60, 50)
                } else {
                    Color32::from_rgb(250, 220, 80)
                };
                painter.circle_filled(pos, 4.0, colour);
            }
            text += &format!(" · mask {mask:#x}");
            if layout.on_light_disk {
                text += " (light samples)";
            }
        }
        _ => {
            text += " · no per-sample mask (a filtered lookup)";
        }
    }
    painter.text(
        crop.left_bottom() + Vec2::new(0.0, 10.0),
        egui::Align2::LEFT_TOP,
        text,
        egui::FontId::proportional(13.0),
        Color32::WHITE,
    );
}
