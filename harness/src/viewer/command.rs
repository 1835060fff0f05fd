//! Keys → viewer actions, and `--script FILE`: timed key and mouse events that drive the
//! viewer exactly as a user's would (the window translates real events into the same
//! [`Event`]s, so a script exercises the same code).
//!
//! ## Keys
//! | key | action |
//! |---|---|
//! | W A S D, Q E, Shift | fly (orbit: W/S closer/further); Shift ×4 |
//! | drag (left button), wheel | turn; fly speed (orbit: distance) |
//! | Tab | fly ⇄ orbit |
//! | R | reset to the scene's default view |
//! | 1 … 9 | the n-th method of `--methods` |
//! | + / − (= / -) | finer / coarser: ε ÷ √2 or budget × √2 (and back) |
//! | K | next kernel (square, circle, ellipse, gaussian) |
//! | F | show the reference instead of the method |
//! | G | FLIP heat map of the frame against the reference |
//! | H | hole mask: red where the reference has a splat and the frame none |
//! | L | colour the drawn nodes / clouds by level (LPC, MWKD, Potree) |
//! | C | compute the FLIP of the current frame (shown in the HUD) |
//! | Space | add a keyframe at the current pose |
//! | Enter | save the keyframes as a `.toml` path (`run --path` reads it) |
//! | P | play a path back (`--play FILE`, else the last one saved) |
//! | F12 | screenshot: frame + reference PNGs and the pose's sidecar `.toml` |
//! | Esc | quit |
//!
//! ## Script
//! One event per line, `FRAME EVENT [ARGS]`, `#` starts a comment; frames are counted from
//! 0 and must not decrease; an event happens before its frame is drawn:
//! ```text
//! 0   down w        # a key goes down …
//! 15  up w          # … and up
//! 16  drag 40 -8    # the mouse dragged by (dx, dy) pixels
//! 17  scroll 1      # wheel notches
//! 18  press space   # down and up: add a keyframe
//! 30  quit
//! ```
//! Under a script the clock is virtual, [`SCRIPT_FPS`] frames per second, so a script moves
//! the camera the same way on any machine. A script without `quit` leaves the window open
//! after its last event (the user takes over; `--frames N` quits after N frames instead).

use super::control::{Input, Key};

/// Frames per second of a script's virtual clock.
pub const SCRIPT_FPS: f64 = 30.0;

/// What a key does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// A movement key (acts while held).
    Move(Key),
    /// Fly ⇄ orbit.
    ToggleMode,
    /// Back to the default view.
    Reset,
    /// The n-th method (0-based).
    Method(usize),
    /// Finer (ε smaller, budget larger).
    Finer,
    /// Coarser.
    Coarser,
    /// Next kernel.
    Kernel,
    /// Show the reference.
    Reference,
    /// Show the FLIP heat map.
    FlipMap,
    /// Show the hole mask.
    Holes,
    /// Colour chunks by level.
    Levels,
    /// Measure the current frame's FLIP.
    Measure,
    /// Add a keyframe.
    AddKey,
    /// Save the keyframes.
    SavePath,
    /// Play a path back.
    Play,
    /// Screenshot.
    Screenshot,
    /// Quit.
    Quit,
}

/// Every key name [`action`] knows (`=` and `-` are also `plus` and `minus`), as a script's
/// error lists them.
pub const KEY_NAMES: &[&str] = &[
    "w", "a", "s", "d", "q", "e", "shift", "tab", "r", "plus", "minus", "k", "f", "g", "h", "l",
    "c", "space", "enter", "p", "f12", "escape", "1", "2", "3", "4", "5", "6", "7", "8", "9",
];

/// The action of the key named `name` (lower case, as scripts spell it; the window maps
/// its keys to these names).
pub fn action(name: &str) -> Option<Action> {
    Some(match name {
        "w" => Action::Move(Key::W),
        "a" => Action::Move(Key::A),
        "s" => Action::Move(Key::S),
        "d" => Action::Move(Key::D),
        "q" => Action::Move(Key::Q),
        "e" => Action::Move(Key::E),
        "shift" => Action::Move(Key::Shift),
        "tab" => Action::ToggleMode,
        "r" => Action::Reset,
        "plus" | "=" => Action::Finer,
        "minus" | "-" => Action::Coarser,
        "k" => Action::Kernel,
        "f" => Action::Reference,
        "g" => Action::FlipMap,
        "h" => Action::Holes,
        "l" => Action::Levels,
        "c" => Action::Measure,
        "space" => Action::AddKey,
        "enter" => Action::SavePath,
        "p" => Action::Play,
        "f12" => Action::Screenshot,
        "escape" => Action::Quit,
        d if d.len() == 1 && ("1"..="9").contains(&d) => {
            Action::Method(usize::from(d.as_bytes()[0] - b'1'))
        }
        _ => return None,
    })
}

/// One input event, from the window or a script.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A key went down (`true`) or up, by name ([`action`]).
    Key(String, bool),
    /// The mouse dragged by (dx, dy) pixels.
    Drag(f64, f64),
    /// Wheel notches.
    Scroll(f64),
    /// Quit.
    Quit,
}

/// What an event asks of the viewer: camera input, or an action.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Effect {
    /// Camera input ([`super::control::Controller::input`]).
    Camera(Input),
    /// An action taken once (on the key's press).
    Act(Action),
    /// Nothing (a key without an action, or an action key's release).
    None,
}

/// The effect of `ev`.
pub fn effect(ev: &Event) -> Effect {
    match ev {
        Event::Drag(dx, dy) => Effect::Camera(Input::Drag(*dx, *dy)),
        Event::Scroll(n) => Effect::Camera(Input::Scroll(*n)),
        Event::Quit => Effect::Act(Action::Quit),
        Event::Key(name, down) => match (action(name), down) {
            (Some(Action::Move(k)), true) => Effect::Camera(Input::Down(k)),
            (Some(Action::Move(k)), false) => Effect::Camera(Input::Up(k)),
            (Some(a), true) => Effect::Act(a),
            _ => Effect::None,
        },
    }
}

/// A parsed script: events by frame, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Script {
    /// (frame, event), frames non-decreasing.
    pub events: Vec<(u64, Event)>,
}

impl Script {
    /// Parses a script's text; errors name the line.
    pub fn parse(text: &str) -> Result<Script, String> {
        let mut events = Vec::new();
        let mut last = 0;
        for (n, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let err = |msg: String| format!("line {}: {msg} ('{}')", n + 1, raw.trim());
            let words: Vec<&str> = line.split_whitespace().collect();
            let frame: u64 = words[0]
                .parse()
                .map_err(|_| err(format!("'{}' is not a frame number", words[0])))?;
            if frame < last {
                return Err(err(format!("frame {frame} comes after frame {last}")));
            }
            last = frame;
            let args = &words[1..];
            let num = |s: &str| -> Result<f64, String> {
                s.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| err(format!("'{s}' is not a finite number")))
            };
            let key = |s: &str| -> Result<String, String> {
                let k = s.to_ascii_lowercase();
                action(&k).map(|_| k).ok_or_else(|| {
                    err(format!("unknown key '{s}' (keys: {})", KEY_NAMES.join(" ")))
                })
            };
            match args {
                ["down", k] => events.push((frame, Event::Key(key(k)?, true))),
                ["up", k] => events.push((frame, Event::Key(key(k)?, false))),
                ["press", k] => {
                    let k = key(k)?;
                    events.push((frame, Event::Key(k.clone(), true)));
                    events.push((frame, Event::Key(k, false)));
                }
                ["drag", dx, dy] => events.push((frame, Event::Drag(num(dx)?, num(dy)?))),
                ["scroll", s] => events.push((frame, Event::Scroll(num(s)?))),
                ["quit"] => events.push((frame, Event::Quit)),
                _ => {
                    return Err(err(
                        "expected 'down KEY', 'up KEY', 'press KEY', 'drag DX DY', \
                         'scroll N' or 'quit' after the frame"
                            .into(),
                    ));
                }
            }
        }
        Ok(Script { events })
    }

    /// The events of frame `frame`.
    pub fn at(&self, frame: u64) -> impl Iterator<Item = &Event> {
        self.events
            .iter()
            .filter(move |(f, _)| *f == frame)
            .map(|(_, e)| e)
    }

    /// The last frame with an event.
    pub fn last_frame(&self) -> Option<u64> {
        self.events.last().map(|(f, _)| *f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_documented_key_has_an_action() {
        // Every name (the README's list is KEY_NAMES): the next test.
        assert_eq!(action("3"), Some(Action::Method(2)));
        assert_eq!(action("0"), None);
        assert_eq!(action("x"), None);
    }

    #[test]
    fn movement_keys_act_while_held_and_others_on_press() {
        let down = |k: &str| effect(&Event::Key(k.into(), true));
        let up = |k: &str| effect(&Event::Key(k.into(), false));
        assert_eq!(down("w"), Effect::Camera(Input::Down(Key::W)));
        assert_eq!(up("w"), Effect::Camera(Input::Up(Key::W)));
        assert_eq!(down("space"), Effect::Act(Action::AddKey));
        assert_eq!(up("space"), Effect::None);
        assert_eq!(down("x"), Effect::None);
        assert_eq!(
            effect(&Event::Drag(1.0, 2.0)),
            Effect::Camera(Input::Drag(1.0, 2.0))
        );
    }

    #[test]
    fn a_script_parses_to_events_by_frame() {
        let s = Script::parse(
            "# a script\n0 down W\n15 up w # release\n\n16 drag 40 -8\n17 scroll 1.5\n\
             18 press f12\n30 quit\n",
        )
        .expect("parses");
        assert_eq!(
            s.events,
            vec![
                (0, Event::Key("w".into(), true)),
                (15, Event::Key("w".into(), false)),
                (16, Event::Drag(40.0, -8.0)),
                (17, Event::Scroll(1.5)),
                (18, Event::Key("f12".into(), true)),
                (18, Event::Key("f12".into(), false)),
                (30, Event::Quit),
            ]
        );
        assert_eq!(s.at(18).count(), 2);
        assert_eq!(s.last_frame(), Some(30));
    }

    /// The list a bad key's error shows is exactly the keys `action` knows: each listed name
    /// maps to an action, and no other name of one or two letters, digit or common key does.
    #[test]
    fn the_listed_key_names_are_exactly_the_known_ones() {
        for k in KEY_NAMES {
            assert!(action(k).is_some(), "{k}");
        }
        let mut others: Vec<String> = (b'a'..=b'z').map(|c| (c as char).to_string()).collect();
        others.extend((b'0'..=b'9').map(|c| (c as char).to_string()));
        others.extend((1..=12).map(|n| format!("f{n}")));
        others.extend(
            [
                "ctrl",
                "alt",
                "up",
                "down",
                "left",
                "right",
                "return",
                "esc",
                "backspace",
            ]
            .map(String::from),
        );
        for k in others.iter().filter(|k| !KEY_NAMES.contains(&k.as_str())) {
            assert!(action(k).is_none(), "'{k}' works but is not listed");
        }
    }

    #[test]
    fn bad_scripts_name_the_line() {
        for (text, want) in [
            ("0 down w\nx up w", "line 2: 'x' is not a frame number"),
            ("5 down w\n4 up w", "line 2: frame 4 comes after frame 5"),
            (
                "0 press zz",
                "line 1: unknown key 'zz' (keys: w a s d q e shift",
            ),
            ("0 drag 1 nan", "line 1: 'nan' is not a finite number"),
            ("0 jump", "line 1: expected"),
        ] {
            let e = Script::parse(text).expect_err(text);
            assert!(e.starts_with(want), "{text}: {e}");
        }
    }
}
