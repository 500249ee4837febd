//! The viewer's egui interface: the side panel (status, exposure and
//! tone map, camera, point lights, and the selected material's editors)
//! and the image area's orbit and zoom input. `State::ui` draws it once a
//! frame and reports what changed ([`UiOutcome`]).

use super::{params, State};
use isolux_io::Tonemap;
use isolux_render::Environment;

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
        }
        egui::SidePanel::right("isolux-panel")
            .default_width(300.0)
            .show(ctx, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.panel(ui, info, &mut out));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ctx, |ui| {
                let rect = ui.max_rect();
                let r = ui.allocate_rect(rect, egui::Sense::click_and_drag());
                out.viewport = rect;
                if r.dragged() {
                    let d = r.drag_delta();
                    let shift = ui.input(|i| i.modifiers.shift);
                    if r.dragged_by(egui::PointerButton::Primary) && !shift {
                        self.orbit.drag(d.x as f64, d.y as f64);
                    } else {
                        self.orbit.pan(d.x as f64, d.y as f64, rect.height() as f64);
                    }
                    out.camera = true;
                    out.dragging = true;
                }
                // A click shows the material under the cursor in the
                // panel; a double click also orbits about the point.
                let double = r.double_clicked_by(egui::PointerButton::Primary);
                if double || r.clicked_by(egui::PointerButton::Primary) {
                    if let Some(pos) = r.interact_pointer_pos() {
                        let at = pos - rect.min;
                        let (w, h) = (rect.width() as f64, rect.height() as f64);
                        out.camera |= self.click(at.x as f64, at.y as f64, w, h, double);
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
            });
        if !ctx.wants_keyboard_input() && ctx.input(|i| i.key_pressed(egui::Key::P)) {
            out.screenshot = true;
        }
        self.history.observe(&self.edited());
        out
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
                     click an object to edit its material, double-click to orbit about the point",
                );
                let mut c = false;
                c |= ui
                    .add(egui::Slider::new(&mut self.orbit.fov_y, 5.0..=120.0).text("fov_y"))
                    .changed();
                c |= ui
                    .add(
                        egui::DragValue::new(&mut self.orbit.distance)
                            .speed(0.01)
                            .range(1e-3..=1e5)
                            .prefix("distance "),
                    )
                    .changed();
                if ui.button("Reset to the scene's camera").clicked() {
                    self.orbit = self.initial_orbit;
                    c = true;
                }
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
