//! The viewer's window (winit, X11): turns key and mouse events into [`Event`]s for the
//! [`Session`], draws a frame per redraw and presents it with the HUD. With a script
//! (`--script`) its events come in at their frames on a virtual clock; `--frames N` ends the
//! loop after N frames. A machine without a display gets an error naming what is missing.

use std::sync::Arc;
use std::time::Instant;

use anyhow::Context as _;
use scenes::Progress;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::command::{Event, SCRIPT_FPS, Script};
use super::present::{Presenter, surface_format};
use super::session::Session;
use crate::gpu::Gpu;

/// The window system, opened before the GPU (the instance takes its display handle).
pub struct WindowSystem {
    event_loop: EventLoop<()>,
}

/// What is missing when the viewer cannot open a window: `None` when a display is named.
pub fn missing_display() -> Option<String> {
    let set = |v: &str| std::env::var_os(v).is_some_and(|s| !s.is_empty());
    (!set("DISPLAY")).then(|| {
        let wayland = if set("WAYLAND_DISPLAY") {
            " (WAYLAND_DISPLAY is set, but the viewer speaks X11 only: start XWayland)"
        } else {
            ""
        };
        format!(
            "no display: DISPLAY is not set{wayland}; `splatbench view` opens an X11 window. On \
             a machine without a screen, run it under Xvfb: xvfb-run -s '-screen 0 1920x1080x24' \
             splatbench view …"
        )
    })
}

impl WindowSystem {
    /// Connects to the X server named by `DISPLAY`.
    pub fn open() -> anyhow::Result<WindowSystem> {
        if let Some(why) = missing_display() {
            anyhow::bail!(why);
        }
        let name = std::env::var("DISPLAY").unwrap_or_default();
        let event_loop = EventLoop::new()
            .with_context(|| format!("cannot open the X11 display '{name}' (DISPLAY)"))?;
        Ok(WindowSystem { event_loop })
    }

    /// A GPU whose instance can present to this display's windows.
    pub fn gpu(&self) -> anyhow::Result<Option<Gpu>> {
        let handle = self.event_loop.owned_display_handle();
        Gpu::from_instance(
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle_from_env(
                Box::new(handle),
            )),
            |_| {},
        )
    }
}

/// How the loop runs.
pub struct LoopConfig {
    /// Scripted events (their frames on a virtual clock of [`SCRIPT_FPS`]).
    pub script: Option<Script>,
    /// Stop after this many frames.
    pub frames: Option<u64>,
    /// The window's title.
    pub title: String,
    /// Save the window's last picture (frame and HUD) here on quitting.
    pub window_shot: Option<std::path::PathBuf>,
}

/// Per-frame times the loop measured, ms.
#[derive(Debug, Clone, Default)]
pub struct LoopTimes {
    /// Select + draw + overlays ([`Session::frame`]).
    pub frame_ms: Vec<f64>,
    /// The HUD drawn (when due) and the frame presented.
    pub present_ms: Vec<f64>,
    /// Of `present_ms`, drawing the HUD's text (0 when the last one was still current).
    pub hud_ms: Vec<f64>,
}

/// The HUD panel's widest, pixels: its longest line (≈ 1,100 px) unbroken.
const HUD_MAX_WIDTH: u32 = 1100;

struct App<'s, 'g> {
    session: &'s mut Session<'g>,
    gpu: &'g Gpu,
    cfg: LoopConfig,
    progress: &'s dyn Progress,
    window: Option<Arc<Window>>,
    surface: Option<(wgpu::Surface<'static>, wgpu::SurfaceConfiguration)>,
    presenter: Option<Presenter>,
    last: Option<Instant>,
    cursor: Option<(f64, f64)>,
    dragging: bool,
    error: Option<anyhow::Error>,
    times: LoopTimes,
    started: Instant,
    /// The HUD drawn last: its lines, when (seconds since start), the image.
    hud: Option<(Vec<String>, f64, crate::image::Image)>,
    /// Times the HUD was drawn (its image's generation for the presenter).
    hud_draws: u64,
    /// Rows at the window's top kept for the HUD, set when the window opens
    /// ([`super::present::frame_rect`]).
    band: u32,
}

/// Opens the window and runs the viewer until quit (Esc, the window closed, a script's
/// `quit` or `cfg.frames` frames).
pub fn run<'g>(
    display: WindowSystem,
    gpu: &'g Gpu,
    session: &mut Session<'g>,
    cfg: LoopConfig,
    progress: &dyn Progress,
) -> anyhow::Result<LoopTimes> {
    let mut app = App {
        session,
        gpu,
        cfg,
        progress,
        window: None,
        surface: None,
        presenter: None,
        last: None,
        cursor: None,
        dragging: false,
        error: None,
        times: LoopTimes::default(),
        started: Instant::now(),
        hud: None,
        hud_draws: 0,
        band: 0,
    };
    display
        .event_loop
        .run_app(&mut app)
        .context("the window's event loop")?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(app.times),
    }
}

/// The name [`super::command::action`] knows a key by.
pub fn key_name(code: KeyCode) -> Option<&'static str> {
    Some(match code {
        KeyCode::KeyW => "w",
        KeyCode::KeyA => "a",
        KeyCode::KeyS => "s",
        KeyCode::KeyD => "d",
        KeyCode::KeyQ => "q",
        KeyCode::KeyE => "e",
        KeyCode::ShiftLeft | KeyCode::ShiftRight => "shift",
        KeyCode::Tab => "tab",
        KeyCode::KeyR => "r",
        KeyCode::Equal | KeyCode::NumpadAdd => "plus",
        KeyCode::Minus | KeyCode::NumpadSubtract => "minus",
        KeyCode::KeyK => "k",
        KeyCode::KeyF => "f",
        KeyCode::KeyG => "g",
        KeyCode::KeyH => "h",
        KeyCode::KeyL => "l",
        KeyCode::KeyC => "c",
        KeyCode::Space => "space",
        KeyCode::Enter | KeyCode::NumpadEnter => "enter",
        KeyCode::KeyP => "p",
        KeyCode::F12 => "f12",
        KeyCode::Escape => "escape",
        KeyCode::Digit1 => "1",
        KeyCode::Digit2 => "2",
        KeyCode::Digit3 => "3",
        KeyCode::Digit4 => "4",
        KeyCode::Digit5 => "5",
        KeyCode::Digit6 => "6",
        KeyCode::Digit7 => "7",
        KeyCode::Digit8 => "8",
        KeyCode::Digit9 => "9",
        _ => return None,
    })
}

impl App<'_, '_> {
    fn open_window(&mut self, el: &ActiveEventLoop) -> anyhow::Result<()> {
        let s = self.session.settings();
        // The HUD's band: its height at the frame's width now, and one line more for a
        // message or a loader line that breaks later; the frame goes under it, 1:1.
        let hud = super::hud::draw(&self.session.hud(), s.width.clamp(1, HUD_MAX_WIDTH))?;
        self.band = hud.height + super::hud::LINE_PX;
        let window = Arc::new(
            el.create_window(
                Window::default_attributes()
                    .with_title(self.cfg.title.clone())
                    .with_inner_size(PhysicalSize::new(s.width, s.height + self.band)),
            )
            .context("creating the viewer's window")?,
        );
        let surface = self
            .gpu
            .instance
            .create_surface(window.clone())
            .context("creating a wgpu surface for the window")?;
        let caps = surface.get_capabilities(&self.gpu.handle);
        let format = surface_format(&caps.formats).with_context(|| {
            format!(
                "adapter '{}' cannot present to this window (no surface format)",
                self.gpu.adapter.name
            )
        })?;
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
        };
        surface.configure(&self.gpu.device, &config);
        self.presenter = Some(Presenter::new(self.gpu, format));
        self.surface = Some((surface, config));
        window.request_redraw();
        self.window = Some(window);
        Ok(())
    }

    fn redraw(&mut self) -> anyhow::Result<()> {
        let frame = self.session.frames();
        let dt = match (&self.cfg.script, self.last) {
            (Some(_), _) => 1.0 / SCRIPT_FPS,
            (None, Some(t)) => t.elapsed().as_secs_f64().min(0.25),
            (None, None) => 0.0,
        };
        self.last = Some(Instant::now());
        if let Some(script) = &self.cfg.script {
            let events: Vec<Event> = script.at(frame).cloned().collect();
            for ev in &events {
                self.session.event(ev)?;
            }
        }
        if self.session.quit_requested() {
            return Ok(());
        }
        self.session.frame(dt, self.progress)?;
        let t = Instant::now();
        self.present()?;
        self.times.frame_ms.push(self.session.info.frame_ms);
        self.times.present_ms.push(t.elapsed().as_secs_f64() * 1e3);
        Ok(())
    }

    fn present(&mut self) -> anyhow::Result<()> {
        let (Some((surface, config)), Some(presenter)) = (&self.surface, &mut self.presenter)
        else {
            return Ok(());
        };
        let texture = match surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            // Resized or hidden meanwhile: reconfigure and skip this present.
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                surface.configure(&self.gpu.device, config);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(());
            }
            other => anyhow::bail!("the window's surface: {other:?}"),
        };
        let view = texture.texture.create_view(&Default::default());
        let s = self.session.settings();
        let lines = self.session.hud();
        let now = self.started.elapsed().as_secs_f64();
        let width = config.width.clamp(1, HUD_MAX_WIDTH);
        let drawn = self.hud.as_ref().map(|(l, at, _)| (l.as_slice(), *at));
        let resized = self
            .hud
            .as_ref()
            .is_some_and(|(_, _, img)| img.width != width);
        let t = Instant::now();
        if resized || super::hud::needs_redraw(drawn, &lines, now) {
            let img = super::hud::draw(&lines, width)?;
            self.hud = Some((lines, now, img));
            self.hud_draws += 1;
        }
        self.times.hud_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let Some((_, _, hud)) = &self.hud else {
            return Ok(());
        };
        // A HUD taller than its band (a message or a loader line broken over more lines):
        // the band grows and the window with it, so the frame stays 1:1 and uncovered; until
        // the window system resizes it, the frame is scaled to what is left.
        if hud.height > self.band {
            let grow = hud.height - self.band;
            self.band = hud.height;
            if let Some(w) = &self.window {
                let size = w.inner_size();
                let _ = w.request_inner_size(PhysicalSize::new(size.width, size.height + grow));
            }
        }
        presenter.present(
            self.gpu,
            self.session.display(),
            (s.width, s.height),
            (hud, self.hud_draws),
            self.band,
            &view,
            (config.width, config.height),
        );
        self.gpu.queue.present(texture);
        Ok(())
    }

    fn input(&mut self, ev: &WindowEvent) -> anyhow::Result<()> {
        let event = match ev {
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return Ok(());
                };
                let Some(name) = key_name(code) else {
                    return Ok(());
                };
                if event.repeat {
                    return Ok(());
                }
                Event::Key(name.into(), event.state == ElementState::Pressed)
            }
            WindowEvent::MouseInput {
                button: MouseButton::Left,
                state,
                ..
            } => {
                self.dragging = *state == ElementState::Pressed;
                return Ok(());
            }
            WindowEvent::CursorMoved { position, .. } => {
                let now = (position.x, position.y);
                let before = self.cursor.replace(now);
                match before {
                    Some(b) if self.dragging => Event::Drag(now.0 - b.0, now.1 - b.1),
                    _ => return Ok(()),
                }
            }
            WindowEvent::MouseWheel { delta, .. } => match delta {
                MouseScrollDelta::LineDelta(_, y) => Event::Scroll(f64::from(*y)),
                MouseScrollDelta::PixelDelta(p) => Event::Scroll(p.y / 50.0),
            },
            _ => return Ok(()),
        };
        self.session.event(&event)
    }

    fn window_shot(&mut self) -> anyhow::Result<()> {
        let (Some(file), Some((_, config))) = (self.cfg.window_shot.take(), &self.surface) else {
            return Ok(());
        };
        let s = self.session.settings();
        let hud = super::hud::draw(&self.session.hud(), config.width.clamp(1, HUD_MAX_WIDTH))?;
        let img = super::present::window_image(
            self.gpu,
            self.session.display(),
            (s.width, s.height),
            (&hud, self.band),
            (config.width, config.height),
        )?;
        img.save_png(&file)?;
        Ok(())
    }

    fn done(&self) -> bool {
        self.session.quit_requested() || self.cfg.frames.is_some_and(|n| self.session.frames() >= n)
    }
}

impl ApplicationHandler for App<'_, '_> {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.window.is_none()
            && let Err(e) = self.open_window(el)
        {
            self.error = Some(e);
            el.exit();
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, ev: WindowEvent) {
        let result = match &ev {
            WindowEvent::CloseRequested => {
                el.exit();
                return;
            }
            WindowEvent::Resized(size) => {
                if let Some((surface, config)) = &mut self.surface
                    && size.width > 0
                    && size.height > 0
                {
                    config.width = size.width;
                    config.height = size.height;
                    surface.configure(&self.gpu.device, config);
                }
                Ok(())
            }
            WindowEvent::RedrawRequested => self.redraw(),
            _ => self.input(&ev),
        };
        if let Err(e) = result {
            self.error = Some(e);
            el.exit();
            return;
        }
        if self.done() {
            if let Err(e) = self.window_shot() {
                self.error = Some(e);
            }
            el.exit();
        } else if matches!(ev, WindowEvent::RedrawRequested)
            && let Some(w) = &self.window
        {
            w.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::viewer::command::action;

    #[test]
    fn every_mapped_key_has_an_action() {
        for code in [
            KeyCode::KeyW,
            KeyCode::ShiftRight,
            KeyCode::NumpadAdd,
            KeyCode::Minus,
            KeyCode::NumpadEnter,
            KeyCode::F12,
            KeyCode::Digit9,
        ] {
            let name = key_name(code).expect("mapped");
            assert!(action(name).is_some(), "{code:?} → {name}");
        }
        assert_eq!(key_name(KeyCode::KeyZ), None);
    }
}
