//! `izb view --script FILE`: timed actions that drive the real window, so
//! a test (or a README screenshot) needs no person. One action per line,
//! `#` starts a comment:
//!
//! | line | effect |
//! |---|---|
//! | `wait SECONDS` | pause the script |
//! | `method NAME` | the left (or only) method (`izb32`, `pcf3-2048`, …) |
//! | `split NAME` / `split off` | a second method right of the divider |
//! | `divider FRACTION` | the divider's place, 0–1 of the image width |
//! | `view shaded\|lit\|candidates\|error` | what the image shows |
//! | `light YAW PITCH` | the light turned from the scene's, degrees |
//! | `light-size SIZE` | the light's size (degrees, or a point light's radius) |
//! | `orbit YAW PITCH` | the camera orbited from the scene's, degrees |
//! | `zoom FACTOR` | the camera's distance to its target, × the scene's |
//! | `resize W H` | ask the window for an inner size |
//! | `magnify X Y` / `magnify off` | put the magnifier on image pixel (X, Y), or hide it |
//! | `overlay on\|off` | show or hide the overlay of times and error |
//! | `wait-truth SPP` | wait until the progressive truth has SPP samples |
//! | `screenshot DIR` | once the frame shown is the current one: `render`'s outputs and `window.png` into DIR |
//! | `quit` | close the window and exit 0 |

use super::state::{method_kind, ViewKind};
use std::path::{Path, PathBuf};

/// One scripted action.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Wait(f64),
    Method(String),
    Split(Option<String>),
    Divider(f32),
    View(ViewKind),
    Light([f64; 2]),
    LightSize(f64),
    Orbit([f64; 2]),
    Zoom(f64),
    Resize([u32; 2]),
    Magnify(Option<[u32; 2]>),
    Overlay(bool),
    WaitTruth(u32),
    Screenshot(PathBuf),
    Quit,
}

/// Reads and parses a script file, naming the file and line of any error.
pub fn load(path: &Path) -> Result<Vec<Action>, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read the script {}: {e}", path.display()))?;
    parse(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Parses a script.
pub fn parse(text: &str) -> Result<Vec<Action>, String> {
    let mut actions = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let action = parse_line(&words).map_err(|e| format!("line {}: `{line}`: {e}", n + 1))?;
        actions.push(action);
    }
    Ok(actions)
}

fn parse_line(words: &[&str]) -> Result<Action, String> {
    let args = &words[1..];
    let want = |n: usize| {
        if args.len() == n {
            Ok(())
        } else {
            Err(format!("takes {n} argument(s), got {}", args.len()))
        }
    };
    let number = |s: &str| -> Result<f64, String> {
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not a finite number"))
    };
    let count = |s: &str| -> Result<u32, String> {
        s.parse::<u32>()
            .map_err(|_| format!("`{s}` is not a whole number"))
    };
    Ok(match words[0] {
        "wait" => {
            want(1)?;
            let s = number(args[0])?;
            if s < 0.0 {
                return Err("a wait cannot be negative".into());
            }
            Action::Wait(s)
        }
        "method" => {
            want(1)?;
            method_kind(args[0])?;
            Action::Method(args[0].into())
        }
        "split" => {
            want(1)?;
            if args[0] == "off" {
                Action::Split(None)
            } else {
                method_kind(args[0])?;
                Action::Split(Some(args[0].into()))
            }
        }
        "divider" => {
            want(1)?;
            let f = number(args[0])?;
            if !(0.0..=1.0).contains(&f) {
                return Err("the divider lies in 0–1".into());
            }
            Action::Divider(f as f32)
        }
        "view" => {
            want(1)?;
            Action::View(ViewKind::parse(args[0]).ok_or("views: shaded, lit, candidates, error")?)
        }
        "light" => {
            want(2)?;
            Action::Light([number(args[0])?, number(args[1])?])
        }
        "light-size" => {
            want(1)?;
            Action::LightSize(number(args[0])?)
        }
        "orbit" => {
            want(2)?;
            Action::Orbit([number(args[0])?, number(args[1])?])
        }
        "zoom" => {
            want(1)?;
            let z = number(args[0])?;
            if z <= 0.0 {
                return Err("the zoom factor must be positive".into());
            }
            Action::Zoom(z)
        }
        "resize" => {
            want(2)?;
            Action::Resize([count(args[0])?, count(args[1])?])
        }
        "magnify" if args == ["off"] => Action::Magnify(None),
        "magnify" => {
            want(2)?;
            Action::Magnify(Some([count(args[0])?, count(args[1])?]))
        }
        "overlay" => {
            want(1)?;
            match args[0] {
                "on" => Action::Overlay(true),
                "off" => Action::Overlay(false),
                _ => return Err("overlay on or overlay off".into()),
            }
        }
        "wait-truth" => {
            want(1)?;
            Action::WaitTruth(count(args[0])?)
        }
        "screenshot" => {
            want(1)?;
            Action::Screenshot(PathBuf::from(args[0]))
        }
        "quit" => {
            want(0)?;
            Action::Quit
        }
        other => return Err(format!("unknown action `{other}`")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_action_parses() {
        let text = "wait 0.5\nmethod izb32 # comment\nsplit pcf3-2048\nsplit off\ndivider 0.3\n\
                    view error\nlight 10 -5\nlight-size 1\norbit 20 5\nzoom 0.8\nresize 640 360\n\
                    magnify 10 20\nwait-truth 16\nscreenshot out/a\nmagnify off\noverlay off\nquit\n";
        let actions = parse(text).unwrap();
        assert_eq!(actions.len(), 17);
        assert_eq!(actions[2], Action::Split(Some("pcf3-2048".into())));
        assert_eq!(actions[6], Action::Light([10.0, -5.0]));
        assert_eq!(actions[14], Action::Magnify(None));
        assert_eq!(actions[16], Action::Quit);
    }

    #[test]
    fn bad_lines_name_line_and_problem() {
        let cases = [
            ("method rt32", "line 1"),
            ("wait\n", "takes 1"),
            ("\nlight 1 nan", "line 2"),
            ("zoom -1", "positive"),
            ("divider 2", "0–1"),
            ("view sideways", "views"),
            ("jump 3", "unknown action"),
        ];
        for (text, needle) in cases {
            let e = parse(text).unwrap_err();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
        assert_eq!(cases.len(), 7);
    }
}
