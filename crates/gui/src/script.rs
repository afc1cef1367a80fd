//! Scripted sessions (`mammaplan gui --script FILE`): the window does, frame after frame,
//! what a surgeon would do with the mouse, through the same actions its buttons call.
//! CI uses it for its screenshot; it also measures the live update rate under a slider
//! drag. One action per line; `#` starts a comment:
//!
//! ```text
//! phantom                         File > Phantom with its landmarks
//! open PATH                       the path field's Open: a scan, landmarks or a case
//! elements N                      the Elements slider (tetrahedra of the finest level)
//! build                           Build model, then wait until it is built
//! implant ID                      both sides (linked), the catalog entry ID
//! custom round W P                both sides, custom round implant (mm)
//! custom anatomic W H P           both sides, custom anatomic implant (mm)
//! move DIRECTION [TIMES]          a move button: left, right, up, down, front, back
//! drag projection FROM TO SECONDS the Projection slider dragged from FROM to TO (mm),
//!                                 a new value every frame
//! wait                            until the simulation has converged or stopped and
//!                                 its deviation map is computed
//! register SCAN LANDMARKS         the post-operative scan registered onto the open one
//!                                 (paths without spaces), then its deviation map
//! display MODE                    pre-operative, simulated, overlay, deviation or
//!                                 post-operative
//! view NAME                       front, left-oblique, left, right-oblique, right
//! muscle on|off                   Show the pectoralis major (once a model is built)
//! up AXIS                         the scan's vertical: +y, -z, ... or automatic
//! stats                           from now on, once a second on stderr: window frames
//!                                 per second, view updates per second (window frames
//!                                 that drew a newer simulated frame) and simulated
//!                                 frames received per second
//! screenshot FILE                 the window as PNG
//! save-case FILE
//! quit
//! ```
//!
//! Errors in the file name its line; an action that fails (a build error, say) ends the
//! program with a message on stderr and exit status 1.

use crate::camera::StandardView;
use crate::display_mode::DisplayMode;
use crate::implant_plan::MoveDirection;
use anyhow::{Context, Result, bail};
use plan::catalog::ShapeKind;
use std::path::{Path, PathBuf};

/// One step of a script.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Phantom,
    Open(PathBuf),
    Elements(usize),
    Build,
    Implant(String),
    Custom {
        kind: ShapeKind,
        width_mm: f64,
        height_mm: f64,
        projection_mm: f64,
    },
    Move(MoveDirection, usize),
    DragProjection {
        from_mm: f64,
        to_mm: f64,
        seconds: f64,
    },
    Wait,
    Register {
        scan: PathBuf,
        landmarks: PathBuf,
    },
    Display(DisplayMode),
    View(StandardView),
    /// Show the pectoralis major under the surface, or not.
    ShowMuscle(bool),
    /// The scan's vertical (`None`: the automatic rule).
    Up(Option<anatomy::Up>),
    Stats,
    Screenshot(PathBuf),
    SaveCase(PathBuf),
    Quit,
}

/// A parsed script: its actions with their line numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Script {
    pub path: PathBuf,
    pub actions: Vec<(usize, Action)>,
}

impl Script {
    /// Reads and parses a script file; errors name the file and line.
    pub fn read(path: &Path) -> Result<Script> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading the script {}", path.display()))?;
        Script::parse(&text, path)
    }

    /// Parses a script; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Script> {
        let mut actions = Vec::new();
        for (index, line) in text.lines().enumerate() {
            let line_number = index + 1;
            let code = line.split('#').next().unwrap_or("").trim();
            if code.is_empty() {
                continue;
            }
            let action = parse_action(code)
                .with_context(|| format!("{} line {line_number}: {code}", path.display()))?;
            actions.push((line_number, action));
        }
        Ok(Script {
            path: path.to_path_buf(),
            actions,
        })
    }
}

fn parse_action(code: &str) -> Result<Action> {
    let words: Vec<&str> = code.split_whitespace().collect();
    let number = |k: usize, what: &str| -> Result<f64> {
        let word = words
            .get(k)
            .with_context(|| format!("expected {what} after `{}`", words[0]))?;
        word.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .with_context(|| format!("{what}: `{word}` is not a number"))
    };
    let rest = || code[words[0].len()..].trim();
    let path = || -> Result<PathBuf> {
        let path = rest();
        if path.is_empty() {
            bail!("expected a file after `{}`", words[0]);
        }
        Ok(PathBuf::from(path))
    };
    let count = |expected: usize| -> Result<()> {
        if words.len() != expected {
            bail!("expected {} words, found {}", expected, words.len());
        }
        Ok(())
    };
    Ok(match words[0] {
        "phantom" => Action::Phantom,
        "open" => Action::Open(path()?),
        "elements" => {
            count(2)?;
            let n = number(1, "a number of elements")?;
            if !(n >= 1.0 && n.fract() == 0.0) {
                bail!("the number of elements must be a positive whole number");
            }
            Action::Elements(n as usize)
        }
        "build" => Action::Build,
        "implant" => {
            count(2)?;
            Action::Implant(words[1].to_string())
        }
        "custom" => match words.get(1) {
            Some(&"round") => {
                count(4)?;
                Action::Custom {
                    kind: ShapeKind::Round,
                    width_mm: number(2, "a diameter (mm)")?,
                    height_mm: number(2, "a diameter (mm)")?,
                    projection_mm: number(3, "a projection (mm)")?,
                }
            }
            Some(&"anatomic") => {
                count(5)?;
                Action::Custom {
                    kind: ShapeKind::Anatomic,
                    width_mm: number(2, "a width (mm)")?,
                    height_mm: number(3, "a height (mm)")?,
                    projection_mm: number(4, "a projection (mm)")?,
                }
            }
            _ => bail!("expected `custom round W P` or `custom anatomic W H P`"),
        },
        "move" => {
            let direction = parse_direction(words.get(1).copied())?;
            let times = match words.len() {
                2 => 1,
                3 => {
                    let times = number(2, "a number of presses")?;
                    if !(times >= 1.0 && times.fract() == 0.0) {
                        bail!("the number of presses must be a positive whole number");
                    }
                    times as usize
                }
                _ => bail!("expected `move DIRECTION [TIMES]`"),
            };
            Action::Move(direction, times)
        }
        "drag" => {
            count(5)?;
            if words[1] != "projection" {
                bail!("only the projection slider can be dragged");
            }
            let seconds = number(4, "a duration (s)")?;
            if seconds <= 0.0 {
                bail!("the duration must be positive");
            }
            Action::DragProjection {
                from_mm: number(2, "a projection (mm)")?,
                to_mm: number(3, "a projection (mm)")?,
                seconds,
            }
        }
        "wait" => Action::Wait,
        "register" => {
            count(3)?;
            Action::Register {
                scan: PathBuf::from(words[1]),
                landmarks: PathBuf::from(words[2]),
            }
        }
        "display" => {
            count(2)?;
            Action::Display(parse_display(words[1])?)
        }
        "view" => {
            count(2)?;
            Action::View(parse_view(words[1])?)
        }
        "muscle" => {
            count(2)?;
            match words[1] {
                "on" => Action::ShowMuscle(true),
                "off" => Action::ShowMuscle(false),
                other => bail!("`muscle` takes on or off, not `{other}`"),
            }
        }
        "up" => {
            count(2)?;
            match words[1] {
                "automatic" => Action::Up(None),
                axis => Action::Up(Some(
                    anatomy::Up::parse(axis).map_err(|e| anyhow::anyhow!("{e}"))?,
                )),
            }
        }
        "stats" => Action::Stats,
        "screenshot" => Action::Screenshot(path()?),
        "save-case" => Action::SaveCase(path()?),
        "quit" => Action::Quit,
        other => bail!("unknown action `{other}`"),
    })
}

/// The direction word of `move`.
fn parse_direction(word: Option<&str>) -> Result<MoveDirection> {
    Ok(match word {
        Some("left") => MoveDirection::Left,
        Some("right") => MoveDirection::Right,
        Some("up") => MoveDirection::Up,
        Some("down") => MoveDirection::Down,
        Some("front") => MoveDirection::Front,
        Some("back") => MoveDirection::Back,
        _ => bail!("expected left, right, up, down, front or back"),
    })
}

/// The mode word of `display`.
fn parse_display(word: &str) -> Result<DisplayMode> {
    Ok(match word {
        "pre-operative" => DisplayMode::PreOperative,
        "simulated" => DisplayMode::Simulated,
        "overlay" => DisplayMode::Overlay,
        "deviation" => DisplayMode::Deviation,
        "post-operative" => DisplayMode::PostOperative,
        other => bail!(
            "unknown display mode `{other}`: pre-operative, simulated, overlay, \
             deviation or post-operative"
        ),
    })
}

/// The view word of `view`.
fn parse_view(word: &str) -> Result<StandardView> {
    Ok(match word {
        "front" => StandardView::Front,
        "left-oblique" => StandardView::LeftOblique,
        "left" => StandardView::Left,
        "right-oblique" => StandardView::RightOblique,
        "right" => StandardView::Right,
        other => bail!("unknown view `{other}`: front, left-oblique, left, right-oblique or right"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_parse_and_bad_lines_are_named() {
        let text = "# CI's session\nphantom\nelements 8000\nbuild\nimplant R-MOD-120\n\
                    move up 2   # two presses\ndrag projection 30 45 2.5\nwait\n\
                    custom anatomic 120 113 42\ndisplay overlay\nview left-oblique\n\
                    screenshot /tmp/shot one.png\nregister post.ply post.json\n\
                    display post-operative\nmuscle on\nquit\n";
        let script = Script::parse(text, Path::new("ci.script")).unwrap();
        let actions: Vec<&Action> = script.actions.iter().map(|(_, a)| a).collect();
        assert_eq!(script.actions[0].0, 2);
        assert_eq!(actions[0], &Action::Phantom);
        assert_eq!(actions[1], &Action::Elements(8000));
        assert_eq!(actions[4], &Action::Move(MoveDirection::Up, 2));
        assert_eq!(
            actions[5],
            &Action::DragProjection {
                from_mm: 30.0,
                to_mm: 45.0,
                seconds: 2.5
            }
        );
        assert_eq!(
            actions[7],
            &Action::Custom {
                kind: ShapeKind::Anatomic,
                width_mm: 120.0,
                height_mm: 113.0,
                projection_mm: 42.0
            }
        );
        assert_eq!(actions[9], &Action::View(StandardView::LeftOblique));
        assert_eq!(
            actions[10],
            &Action::Screenshot(PathBuf::from("/tmp/shot one.png"))
        );
        assert_eq!(
            actions[11],
            &Action::Register {
                scan: PathBuf::from("post.ply"),
                landmarks: PathBuf::from("post.json")
            }
        );
        assert_eq!(actions[12], &Action::Display(DisplayMode::PostOperative));
        assert_eq!(actions[13], &Action::ShowMuscle(true));

        for (line, expected) in [
            ("elements many", "`many` is not a number"),
            ("move sideways", "expected left, right"),
            ("drag width 1 2 3", "only the projection slider"),
            ("fly", "unknown action `fly`"),
            ("screenshot", "expected a file"),
            ("register post.ply", "expected 3 words"),
            ("muscle maybe", "takes on or off"),
        ] {
            let error =
                Script::parse(&format!("phantom\n{line}\n"), Path::new("s.txt")).unwrap_err();
            let message = format!("{error:#}");
            assert!(message.contains("s.txt line 2"), "{message}");
            assert!(message.contains(expected), "{message}");
        }
    }
}
