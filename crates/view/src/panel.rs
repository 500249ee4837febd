//! The viewer's egui interface: the side panel (status, exposure and
//! tone map, camera, point lights, and the selected material's editors)
//! and the image area's orbit and zoom input. `State::ui` draws it once a
//! frame and reports what changed ([`UiOutcome`]).

use super::{orbit, params, State};
use isolux_io::Tonemap;
use isolux_render::Environment;

/// How near (in points) to a light's marker a press grabs the light.
const MARKER_GRAB: f64 = 9.0;

impl State {
    /// The side panel and the image area; returns what changed.
    pub(super) fn ui(&mut self, ctx: &egui::Context, info: &FrameInfo) -> UiOutcome {
        let mut out = UiOutcome::default();
        // Keys that change what the panel shows first, so that the panel
        // drawn below shows the state restored and the status.
        if ctx.input_mut(|i| i.consume_key(egui::Modifiers::COMMAND, egui::Key::S)) {
            self.status = self.save_scene();
        }
        if !ctx.wants_keyboard_input() {
            let shift_z = egui::Modifiers::COMMAND | egui::Modifiers::SHIFT;
            let redo = ctx.input_mut(|i| {
                i.consume_key(shift_z, egui::Key::Z)
                    || i.consume_key(egui::Modifiers::COMMAND, egui::Key::Y)
            });
            let undo =
                !redo && ctx.input_mut(|i| i.consume_key(egui::Modifiers::COMMAND, egui::Key::Z));
            if redo || undo {
                out.scene |= self.undo(undo);
            }
            if ctx.input_mut(|i| i.consume_key(egui::Modifiers::NONE, egui::Key::F)) {
                out.camera |= self.frame();
            }
        }
        egui::SidePanel::right("isolux-panel")
            .default_width(300.0)
            .show(ctx, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.panel(ui, info, &mut out));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ctx, |ui| self.image_ui(ui, &mut out));
        if !ctx.wants_keyboard_input() && ctx.input(|i| i.key_pressed(egui::Key::P)) {
            out.screenshot = true;
        }
        let held = ctx.input(|i| i.pointer.any_down());
        self.history.observe_held(&self.edited(), held);
        out
    }

    /// The image area: orbit (drag), pan (right or middle drag, or
    /// Shift-drag), zoom (wheel), a light moved by dragging its marker,
    /// a click's pick and a double click's focus.
    fn image_ui(&mut self, ui: &mut egui::Ui, out: &mut UiOutcome) {
        let rect = ui.max_rect();
        let r = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        out.viewport = rect;
        let (w, h) = (rect.width() as f64, rect.height() as f64);
        let local = |p: egui::Pos2| p - rect.min;
        let primary = egui::PointerButton::Primary;
        // A drag that starts on a light's marker moves the light.
        if r.drag_started_by(primary) && !ui.input(|i| i.modifiers.shift) {
            self.light_drag = ui.input(|i| i.pointer.press_origin()).and_then(|p| {
                let at = local(p);
                let (i, m) = self.light_at(at.x as f64, at.y as f64, w, h, MARKER_GRAB)?;
                Some((i, egui::vec2(m.x as f32, m.y as f32) - at))
            });
        }
        if !r.dragged() {
            self.light_drag = None;
        } else {
            if let Some((i, offset)) = self.light_drag {
                if let Some(pos) = r.interact_pointer_pos() {
                    let at = local(pos) + offset;
                    out.scene |= self.move_light(i, at.x as f64, at.y as f64, w, h);
                }
            } else {
                let d = r.drag_delta();
                let shift = ui.input(|i| i.modifiers.shift);
                if r.dragged_by(primary) && !shift {
                    self.orbit.drag(d.x as f64, d.y as f64);
                } else {
                    self.orbit.pan(d.x as f64, d.y as f64, h);
                }
                out.camera = true;
            }
            out.dragging = true;
        }
        // A click shows the material under the cursor in the panel (or
        // names the light whose marker it is on); a double click also
        // orbits about the point.
        let double = r.double_clicked_by(primary);
        if double || r.clicked_by(primary) {
            // Where the button was released: with slow frames (a CPU
            // driver's seconds) the pointer may have moved on by the time
            // the frame reads it, and `interact_pointer_pos` is its latest
            // position.
            let released = ui.input(|i| {
                i.events.iter().rev().find_map(|e| match e {
                    egui::Event::PointerButton {
                        pos,
                        button: egui::PointerButton::Primary,
                        pressed: false,
                        ..
                    } => Some(*pos),
                    _ => None,
                })
            });
            if let Some(pos) = released.or(r.interact_pointer_pos()) {
                let at = local(pos);
                let (x, y) = (at.x as f64, at.y as f64);
                match self.light_at(x, y, w, h, MARKER_GRAB) {
                    Some((i, _)) if !double => {
                        let p = self.scene.lights[i].position;
                        self.status = format!(
                            "light {i} at ({:.4}, {:.4}, {:.4}): drag its ring to move it",
                            p.x, p.y, p.z
                        );
                    }
                    _ => out.camera |= self.click(x, y, w, h, double),
                }
                // The panel, drawn before, shows it next frame.
                ui.ctx().request_repaint();
            }
        }
        if r.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.orbit.zoom(scroll as f64 / 50.0);
                out.camera = true;
            }
        }
        self.draw_light_markers(ui, rect, r.hover_pos());
    }

    /// A ring at each point light in front of the eye, filled with its
    /// colour, with its number (hollow on the border for one out of view;
    /// [`State::light_markers`]); the one under the cursor or being
    /// dragged drawn larger.
    fn draw_light_markers(&self, ui: &egui::Ui, rect: egui::Rect, hover: Option<egui::Pos2>) {
        let (w, h) = (rect.width() as f64, rect.height() as f64);
        let markers = self.light_markers(w, h, MARKER_GRAB);
        let hovered = hover.and_then(|p| {
            let at = p - rect.min;
            super::nearest_marker(&markers, at.x as f64, at.y as f64, MARKER_GRAB).map(|(i, _)| i)
        });
        let active = self.light_drag.map(|(i, _)| i).or(hovered);
        if active.is_some() {
            ui.ctx().set_cursor_icon(if self.light_drag.is_some() {
                egui::CursorIcon::Grabbing
            } else {
                egui::CursorIcon::Grab
            });
        }
        let painter = ui.painter_at(rect);
        for (i, m) in markers.into_iter().enumerate() {
            let Some(m) = m else { continue };
            let c = rect.min + egui::vec2(m.x as f32, m.y as f32);
            let e = self.scene.lights[i].intensity;
            let peak = e.r.max(e.g).max(e.b);
            let level = |v: f64| {
                if peak > 0.0 {
                    (255.0 * (v / peak).clamp(0.0, 1.0).powf(1.0 / 2.2)).round() as u8
                } else {
                    0
                }
            };
            // A light out of view: a hollow ring on the border.
            let fill = if m.inside {
                egui::Color32::from_rgb(level(e.r), level(e.g), level(e.b))
            } else {
                egui::Color32::TRANSPARENT
            };
            let radius = if active == Some(i) { 8.0 } else { 6.0 };
            painter.circle_filled(c, radius, fill);
            painter.circle_stroke(
                c,
                radius + 1.0,
                egui::Stroke::new(1.5, egui::Color32::BLACK),
            );
            painter.circle_stroke(
                c,
                radius + 2.5,
                egui::Stroke::new(1.5, egui::Color32::WHITE),
            );
            // The number beside it, on the side towards the centre.
            let right = m.x < 0.5 * w;
            let below = m.y < 0.5 * h;
            let (dx, ax) = if right {
                (radius + 4.0, egui::Align::LEFT)
            } else {
                (-radius - 4.0, egui::Align::RIGHT)
            };
            let (dy, ay) = if below {
                (radius + 2.0, egui::Align::TOP)
            } else {
                (-radius - 2.0, egui::Align::BOTTOM)
            };
            painter.text(
                c + egui::vec2(dx, dy),
                egui::Align2([ax, ay]),
                i.to_string(),
                egui::FontId::proportional(13.0),
                egui::Color32::WHITE,
            );
        }
    }

    fn panel(&mut self, ui: &mut egui::Ui, info: &FrameInfo, out: &mut UiOutcome) {
        ui.heading("Isolux");
        ui.label(&self.file_name);
        ui.label(format!("adapter: {}", info.adapter));
        if info.film.0 > 0 {
            ui.label(format!(
                "{} x {}, {}, {:.1} ms per frame",
                info.film.0, info.film.1, info.mode, info.frame_ms
            ));
        } else {
            ui.label(&info.mode);
        }
        if !self.status.is_empty() {
            ui.label(&self.status);
        }
        ui.separator();
        ui.horizontal(|ui| {
            ui.label("exposure");
            ui.add(egui::Slider::new(&mut self.exposure, -8.0..=8.0).suffix(" stops"));
        });
        ui.horizontal(|ui| {
            ui.label("tone map");
            egui::ComboBox::from_id_salt("tonemap")
                .selected_text(match self.tonemap {
                    Tonemap::Clamp => "clamp",
                    Tonemap::Reinhard => "reinhard",
                })
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut self.tonemap, Tonemap::Clamp, "clamp");
                    ui.selectable_value(&mut self.tonemap, Tonemap::Reinhard, "reinhard");
                });
        });
        ui.horizontal(|ui| {
            if ui.button("Screenshot (P)").clicked() {
                out.screenshot = true;
            }
            if ui
                .button("Save scene (Ctrl+S)")
                .on_hover_text("the scene file with the edits, as <scene>-view-<n>.toml beside it")
                .clicked()
            {
                self.status = self.save_scene();
            }
        });
        ui.horizontal(|ui| {
            let (back, forward) = self.history.depth();
            if ui
                .add_enabled(back > 0, egui::Button::new(format!("Undo ({back})")))
                .on_hover_text("Ctrl+Z: the last edit of a material, light or environment")
                .clicked()
            {
                out.scene |= self.undo(true);
            }
            if ui
                .add_enabled(forward > 0, egui::Button::new(format!("Redo ({forward})")))
                .on_hover_text("Ctrl+Shift+Z or Ctrl+Y")
                .clicked()
            {
                out.scene |= self.undo(false);
            }
        });
        ui.separator();
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| {
                ui.label(
                    "drag the image to orbit, right-drag (or Shift) to pan, wheel to zoom; \
                     click an object to edit its material, double-click to orbit about the \
                     point, F to frame the object clicked",
                );
                let mut c = false;
                c |= ui
                    .add(egui::Slider::new(&mut self.orbit.fov_y, 5.0..=120.0).text("fov_y"))
                    .changed();
                c |= ui
                    .add(
                        egui::DragValue::new(&mut self.orbit.distance)
                            .speed(0.01)
                            .range(orbit::MIN_DISTANCE..=orbit::MAX_DISTANCE)
                            .prefix("distance "),
                    )
                    .changed();
                ui.horizontal(|ui| {
                    if ui.button("Reset to the scene's camera").clicked() {
                        self.orbit = self.initial_orbit;
                        c = true;
                    }
                    if ui
                        .button("Frame (F)")
                        .on_hover_text(
                            "the object clicked last: the same direction, the object \
                             filling the view's height",
                        )
                        .clicked()
                    {
                        c |= self.frame();
                    }
                });
                out.camera |= c;
            });
        egui::CollapsingHeader::new("Lights")
            .default_open(true)
            .show(ui, |ui| self.lights_ui(ui, out));
        egui::CollapsingHeader::new("Environment")
            .default_open(true)
            .show(ui, |ui| self.environment_ui(ui, out));
        egui::CollapsingHeader::new("Materials")
            .default_open(true)
            .show(ui, |ui| self.materials_ui(ui, out));
    }

    /// The point lights' positions and intensities; lights added (above
    /// the eye, lighting the target) and removed.
    fn lights_ui(&mut self, ui: &mut egui::Ui, out: &mut UiOutcome) {
        if self.scene.lights.is_empty() {
            ui.label("no point lights");
        } else {
            ui.label(
                "drag a light's ring in the image to move it (a hollow ring on the border: \
                 out of view that way)",
            );
        }
        let mut remove = None;
        for (i, l) in self.scene.lights.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                ui.label(format!("light {i}"));
                if ui.small_button("remove").clicked() {
                    remove = Some(i);
                }
            });
            ui.horizontal(|ui| {
                ui.label("position");
                for v in [&mut l.position.x, &mut l.position.y, &mut l.position.z] {
                    out.scene |= ui.add(egui::DragValue::new(v).speed(0.02)).changed();
                }
            });
            ui.horizontal(|ui| {
                ui.label("intensity");
                for v in [&mut l.intensity.r, &mut l.intensity.g, &mut l.intensity.b] {
                    out.scene |= ui
                        .add(egui::DragValue::new(v).speed(0.1).range(0.0..=1e9))
                        .changed();
                }
            });
        }
        if let Some(i) = remove {
            self.scene.lights.remove(i);
            self.light_origin.remove(i);
            out.scene = true;
        }
        if ui
            .button("Add point light")
            .on_hover_text("above the eye, lighting the target with an irradiance of about 1")
            .clicked()
        {
            self.scene.lights.push(new_light(&self.orbit));
            self.light_origin.push(None);
            out.scene = true;
        }
    }

    /// A constant environment's radiance, or a map's `scale` (the factor on
    /// the file's texels, as the scene key).
    fn environment_ui(&mut self, ui: &mut egui::Ui, out: &mut UiOutcome) {
        match &mut self.scene.environment {
            Environment::Constant(c) => {
                ui.horizontal(|ui| {
                    ui.label("radiance");
                    for v in [&mut c.r, &mut c.g, &mut c.b] {
                        out.scene |= ui
                            .add(egui::DragValue::new(v).speed(0.01).range(0.0..=1e6))
                            .changed();
                    }
                });
            }
            Environment::Map(map) => {
                let edit = ui
                    .add(
                        egui::DragValue::new(&mut self.env_scale)
                            .speed(0.01)
                            .range(0.0..=1e6)
                            .prefix("map scale "),
                    )
                    .changed();
                if edit {
                    match map.with_scale(self.env_scale) {
                        Ok(m) => {
                            *map = m;
                            out.scene = true;
                        }
                        Err(e) => self.status = e,
                    }
                }
            }
        }
    }

    fn materials_ui(&mut self, ui: &mut egui::Ui, out: &mut UiOutcome) {
        use params::{editor, number, numbers3, Editor, SWITCHABLE};
        use toml::Value;
        if self.tables.is_empty() {
            ui.label("no materials");
            return;
        }
        let names = self.scene.material_names.clone();
        let before = self.selected;
        egui::ComboBox::from_label("material")
            .selected_text(names[self.selected].as_str())
            .show_ui(ui, |ui| {
                for (i, n) in names.iter().enumerate() {
                    ui.selectable_value(&mut self.selected, i, n.as_str());
                }
            });
        if self.selected != before {
            self.material_error = None;
        }
        let i = self.selected;
        let mut changed = false;
        let t = &mut self.tables[i];
        let ty = t
            .get("type")
            .and_then(|v| v.as_str())
            .unwrap_or("")
            .to_string();
        if SWITCHABLE.contains(&ty.as_str()) {
            let mut new_ty = ty.clone();
            egui::ComboBox::from_label("type")
                .selected_text(ty.as_str())
                .show_ui(ui, |ui| {
                    for s in SWITCHABLE {
                        ui.selectable_value(&mut new_ty, s.to_string(), *s);
                    }
                });
            if new_ty != ty {
                *t = params::template(&names[i], &new_ty);
                changed = true;
            }
        } else {
            ui.label(format!(
                "type: {ty} (reads files or other materials: not switchable)"
            ));
        }
        let keys: Vec<String> = t
            .keys()
            .filter(|k| *k != "name" && *k != "type")
            .cloned()
            .collect();
        for k in keys {
            let v = t[&k].clone();
            match editor(&k, &v) {
                Editor::Number => {
                    let mut x = number(&v).unwrap_or(0.0);
                    let speed = (x.abs() * 0.01).max(0.001);
                    if ui
                        .add(
                            egui::DragValue::new(&mut x)
                                .speed(speed)
                                .prefix(format!("{k} ")),
                        )
                        .changed()
                    {
                        t.insert(k, Value::Float(x));
                        changed = true;
                    }
                }
                Editor::Integer(min, max) => {
                    let range = i64::try_from(min).unwrap_or(i64::MAX)
                        ..=i64::try_from(max).unwrap_or(i64::MAX);
                    let mut x = v.as_integer().unwrap_or(*range.start());
                    if ui
                        .add(
                            egui::DragValue::new(&mut x)
                                .speed(0.05)
                                .range(range)
                                .prefix(format!("{k} ")),
                        )
                        .changed()
                    {
                        t.insert(k, Value::Integer(x));
                        changed = true;
                    }
                }
                Editor::Toggle => {
                    let mut b = v.as_bool().unwrap_or(false);
                    if ui.checkbox(&mut b, k.as_str()).changed() {
                        t.insert(k, Value::Boolean(b));
                        changed = true;
                    }
                }
                e @ (Editor::Color | Editor::Vector) => {
                    let mut c = numbers3(&v).unwrap_or([0.0; 3]);
                    let color = e == Editor::Color;
                    let mut edit = false;
                    ui.horizontal(|ui| {
                        ui.label(&k);
                        if color {
                            let mut f = c.map(|x| x.clamp(0.0, 1.0) as f32);
                            if ui.color_edit_button_rgb(&mut f).changed() {
                                c = f.map(|x| x as f64);
                                edit = true;
                            }
                        }
                        for x in c.iter_mut() {
                            let mut d = egui::DragValue::new(x).speed(0.005);
                            if color {
                                d = d.range(0.0..=1.0);
                            }
                            edit |= ui.add(d).changed();
                        }
                    });
                    if edit {
                        t.insert(k, params::array3(c));
                        changed = true;
                    }
                }
                Editor::Choice(options) => {
                    let cur = v.as_str().unwrap_or("").to_string();
                    let mut sel = cur.clone();
                    egui::ComboBox::from_label(k.as_str())
                        .selected_text(cur.as_str())
                        .show_ui(ui, |ui| {
                            for o in &options {
                                ui.selectable_value(&mut sel, o.to_string(), *o);
                            }
                        });
                    if sel != cur {
                        t.insert(k, Value::String(sel));
                        changed = true;
                    }
                }
                Editor::Components => {
                    let mut c = params::components(&v).unwrap_or_default();
                    let mut edit = false;
                    ui.label(&k);
                    for (j, (m, w)) in c.iter_mut().enumerate() {
                        ui.horizontal(|ui| {
                            egui::ComboBox::from_id_salt(("component", j))
                                .selected_text(m.as_str())
                                .show_ui(ui, |ui| {
                                    for n in &names[..i] {
                                        edit |=
                                            ui.selectable_value(m, n.clone(), n.as_str()).changed();
                                    }
                                });
                            edit |= ui
                                .add(
                                    egui::DragValue::new(w)
                                        .speed(0.005)
                                        .range(0.0..=1.0)
                                        .prefix("weight "),
                                )
                                .changed();
                        });
                    }
                    if edit {
                        t.insert(k, params::components_value(&c));
                        changed = true;
                    }
                }
                Editor::ReadOnly => {
                    ui.label(format!("{k} = {v}"));
                }
            }
        }
        if changed {
            match self.rebuild_material(i) {
                Ok(()) => {
                    self.material_error = None;
                    out.scene = true;
                }
                Err(e) => self.material_error = Some(e),
            }
        }
        if let Some(e) = &self.material_error {
            ui.colored_label(egui::Color32::LIGHT_RED, e);
            ui.label("(the last valid version is shown)");
        }
    }
}

/// What the panel reports each frame.
pub(super) struct UiOutcome {
    pub(super) viewport: egui::Rect,
    pub(super) camera: bool,
    pub(super) scene: bool,
    pub(super) dragging: bool,
    pub(super) screenshot: bool,
}

impl Default for UiOutcome {
    fn default() -> Self {
        Self {
            viewport: egui::Rect::NOTHING,
            camera: false,
            scene: false,
            dragging: false,
            screenshot: false,
        }
    }
}

/// What the panel shows about the last frame.
pub(super) struct FrameInfo {
    pub(super) adapter: String,
    pub(super) film: (u32, u32),
    pub(super) mode: String,
    pub(super) frame_ms: f64,
}

/// A light added in the panel: half the view's distance above the eye
/// (a key light over the viewer's shoulder), white, with an intensity
/// that gives an irradiance of 1 (W/m^2, per channel) facing it at the
/// target, so that a diffuse white surface there looks about as bright
/// as under a typical example scene's lamp. The position is rounded to 4
/// significant digits and the intensity to 3, for short numbers in the
/// panel and in a saved scene (the irradiance stays within 0.5% of 1).
fn new_light(orbit: &super::orbit::Orbit) -> isolux_render::PointLight {
    use super::save::round_to;
    let raw = orbit.eye() + 0.5 * orbit.distance * orbit.up;
    let position = glam::DVec3::from_array(round_to(raw.to_array(), 4));
    let r2 = (position - orbit.target).length_squared();
    isolux_render::PointLight {
        position,
        intensity: isolux_core::Rgb::splat(round_to([r2; 3], 3)[0]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An added light sits above the eye and gives the target an
    /// irradiance of 1 facing it.
    #[test]
    fn an_added_light_lights_the_target_from_above_the_eye() {
        let cam = isolux_render::Camera {
            position: glam::DVec3::new(1.0, 3.4, 7.2),
            look_at: glam::DVec3::new(0.5, -0.15, 0.0),
            up: glam::DVec3::Y,
            fov_y: 42.0,
        };
        let orbit = crate::orbit::Orbit::from_camera(&cam);
        let l = new_light(&orbit);
        let r2 = (l.position - cam.look_at).length_squared();
        for c in l.intensity.to_array() {
            assert!((c / r2 - 1.0).abs() < 5e-3, "{c} {r2}");
        }
        assert!((l.position - orbit.eye()).dot(glam::DVec3::Y) > 0.0);
        // Short numbers: 4 and 3 significant digits.
        for x in l.position.to_array() {
            assert!(
                format!("{x}").trim_start_matches(['-', '0', '.']).len() <= 5,
                "{x}"
            );
        }
        assert!(format!("{}", l.intensity.r).len() <= 4, "{:?}", l.intensity);
    }
}
