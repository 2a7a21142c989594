//! Parsers for argument values: sizes, vectors, backgrounds.

use glam::DVec3;

/// What the picture is composited over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    Transparent,
    Color([f32; 3]),
}

impl Background {
    pub fn color(self) -> Option<[f32; 3]> {
        match self {
            Self::Transparent => None,
            Self::Color(c) => Some(c),
        }
    }
}

/// `WxH`, e.g. `512x512`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("'{s}' is not a size; write WIDTHxHEIGHT, e.g. 512x512");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| err())?,
        h.trim().parse().map_err(|_| err())?,
    );
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("size {w}x{h} must be between 1x1 and 16384x16384"));
    }
    Ok((w, h))
}

/// `X,Y,Z` with finite numbers.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let v = parse_numbers(s, 3)
        .ok_or_else(|| format!("'{s}' is not a vector; write X,Y,Z, e.g. 1,0,-2.5"))?;
    Ok(DVec3::new(v[0], v[1], v[2]))
}

/// `white`, `black`, `none`/`transparent`, or `R,G,B` in [0, 1].
pub fn parse_background(s: &str) -> Result<Background, String> {
    Ok(match s {
        "white" => Background::Color([1.0; 3]),
        "black" => Background::Color([0.0; 3]),
        "none" | "transparent" => Background::Transparent,
        _ => {
            let v = parse_numbers(s, 3)
                .filter(|v| v.iter().all(|c| (0.0..=1.0).contains(c)))
                .ok_or_else(|| {
                    format!("'{s}' is not a background; use white, black, none or R,G,B in [0,1]")
                })?;
            Background::Color([v[0] as f32, v[1] as f32, v[2] as f32])
        }
    })
}

fn parse_numbers(s: &str, n: usize) -> Option<Vec<f64>> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()?;
    (v.len() == n && v.iter().all(|x| x.is_finite())).then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rejects() {
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").is_err() && parse_size("0x4").is_err());
        assert_eq!(parse_vec3("1,-2,3.5"), Ok(DVec3::new(1.0, -2.0, 3.5)));
        assert!(parse_vec3("1,2").is_err() && parse_vec3("1,2,nan").is_err());
        assert_eq!(
            parse_background("0,0.5,1"),
            Ok(Background::Color([0.0, 0.5, 1.0]))
        );
        assert!(parse_background("2,0,0").is_err());
    }
}
