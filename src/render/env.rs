//! The environment a path leaving the scene sees: a constant radiance (the benchmarks', and
//! `--env 0` for none), or a sky: a gradient from the horizon to the zenith (y up), a constant
//! ground below the horizon and a small sun disc, which `glsl/pathtrace.comp` samples by
//! next-event estimation and weights against BSDF sampling by multiple importance sampling.

use std::fmt;
use std::str::FromStr;

use glam::DVec3;
use serde::Serialize;

/// A sky: radiance `mix(horizon, zenith, d.y)` for directions `d` above the horizon, `ground`
/// below it, plus `sun_radiance` within `sun_radius_degrees` of `sun_dir`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Sky {
    pub zenith: [f32; 3],
    pub horizon: [f32; 3],
    pub ground: [f32; 3],
    /// Towards the sun (normalised when used).
    pub sun_dir: [f32; 3],
    /// Angular radius of the sun's disc, degrees.
    pub sun_radius_degrees: f32,
    /// Irradiance the sun gives a surface facing it (linear RGB); its disc's radiance is this
    /// over `pi sin^2(radius)`.
    pub sun_irradiance: [f32; 3],
}

impl Default for Sky {
    /// A clear day: a blue zenith over a pale horizon, a grey-brown ground and a sun high on
    /// the viewer's left (seen by the default front camera, which looks down -z), so that a
    /// white object shows its shape: lit faces, shaded faces and shadows.
    fn default() -> Sky {
        Sky {
            zenith: [0.15, 0.25, 0.45],
            horizon: [0.48, 0.53, 0.6],
            ground: [0.18, 0.16, 0.14],
            sun_dir: [-0.45, 0.75, 0.5],
            sun_radius_degrees: 2.0,
            sun_irradiance: [1.45, 1.35, 1.2],
        }
    }
}

impl Sky {
    /// Unit direction towards the sun, in f64.
    pub fn sun_dir_f64(&self) -> DVec3 {
        DVec3::from_array(self.sun_dir.map(f64::from)).normalize()
    }

    /// Radiance within the sun's disc: the irradiance over the projected solid angle of the
    /// disc seen face-on, `pi sin^2(radius)`.
    pub fn sun_radiance(&self) -> [f64; 3] {
        let s = f64::from(self.sun_radius_degrees).to_radians().sin();
        self.sun_irradiance.map(|e| f64::from(e) / (std::f64::consts::PI * s * s))
    }

    /// Solid angle of the sun's disc, `2 pi (1 - cos(radius))`.
    pub fn sun_solid_angle(&self) -> f64 {
        std::f64::consts::TAU * (1.0 - f64::from(self.sun_radius_degrees).to_radians().cos())
    }

    /// Irradiance on a surface of normal `n` from the sky gradient alone (no ground, no sun),
    /// for `n = +y` (exact): `pi h + 2 pi / 3 (z - h)` per channel.
    pub fn sky_irradiance_up(&self) -> [f64; 3] {
        let pi = std::f64::consts::PI;
        std::array::from_fn(|i| {
            let (h, z) = (f64::from(self.horizon[i]), f64::from(self.zenith[i]));
            pi * h + 2.0 * pi / 3.0 * (z - h)
        })
    }

    /// Irradiance from the sun on a surface of unit normal `n` that sees the whole disc: the
    /// disc's radiance times `n . sun_dir * pi sin^2(radius)` (exact for a uniform disc).
    pub fn sun_irradiance_on(&self, n: DVec3) -> [f64; 3] {
        let cos = n.dot(self.sun_dir_f64()).max(0.0);
        self.sun_irradiance.map(|e| f64::from(e) * cos)
    }

    /// Checks the sky's numbers: finite, non-negative, a non-zero sun direction, a radius in
    /// (0, 45] degrees.
    pub fn check(&self) -> Result<(), String> {
        let colours = [self.zenith, self.horizon, self.ground, self.sun_irradiance];
        if !colours.iter().flatten().all(|c| c.is_finite() && *c >= 0.0) {
            return Err(format!("sky colours must be finite and non-negative: {self:?}"));
        }
        let d = DVec3::from_array(self.sun_dir.map(f64::from));
        if !d.is_finite() || d.length() == 0.0 {
            return Err(format!("the sun direction {:?} must be a finite non-zero vector", self.sun_dir));
        }
        if !(self.sun_radius_degrees > 0.0 && self.sun_radius_degrees <= 45.0) {
            return Err(format!("the sun's radius ({} degrees) must be in (0, 45]", self.sun_radius_degrees));
        }
        Ok(())
    }
}

/// `--env`: `sky`, or a constant radiance `v` or `r,g,b` (`0`: no environment).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EnvSpec {
    Sky,
    Constant([f32; 3]),
}

impl EnvSpec {
    pub const HELP: &'static str =
        "`sky` (a sky gradient, a ground and a sun sampled by next-event estimation) or a constant radiance \
         `v` or `r,g,b` (`0`: no environment)";

    /// The default for a scene: no environment when it has emitters, else the sky.
    pub fn default_for(has_emitters: bool) -> EnvSpec {
        if has_emitters {
            EnvSpec::Constant([0.0; 3])
        } else {
            EnvSpec::Sky
        }
    }

    /// Whether nothing at all comes from the environment.
    pub fn is_black(&self) -> bool {
        matches!(self, EnvSpec::Constant(c) if c.iter().all(|&x| x == 0.0))
    }
}

impl FromStr for EnvSpec {
    type Err = String;

    fn from_str(s: &str) -> Result<EnvSpec, String> {
        if s.trim() == "sky" {
            return Ok(EnvSpec::Sky);
        }
        let v: Vec<f32> = s
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("`{s}`: {e}; expected {}", EnvSpec::HELP))?;
        if !(v.len() == 1 || v.len() == 3) || v.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(format!("`{s}`: expected {} (finite, non-negative)", EnvSpec::HELP));
        }
        Ok(EnvSpec::Constant(if v.len() == 1 { [v[0]; 3] } else { [v[0], v[1], v[2]] }))
    }
}

impl fmt::Display for EnvSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EnvSpec::Sky => f.write_str("sky"),
            EnvSpec::Constant([r, g, b]) if r == g && g == b => write!(f, "{r}"),
            EnvSpec::Constant([r, g, b]) => write!(f, "{r},{g},{b}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn env_specs_parse() {
        assert_eq!("sky".parse::<EnvSpec>().unwrap(), EnvSpec::Sky);
        assert_eq!("0".parse::<EnvSpec>().unwrap(), EnvSpec::Constant([0.0; 3]));
        assert!("0".parse::<EnvSpec>().unwrap().is_black());
        assert_eq!("1,0.5,0".parse::<EnvSpec>().unwrap(), EnvSpec::Constant([1.0, 0.5, 0.0]));
        assert_eq!(EnvSpec::Constant([1.0, 0.5, 0.0]).to_string(), "1,0.5,0");
        for bad in ["", "sun", "1,2", "-1", "inf", "1,nan,1"] {
            assert!(bad.parse::<EnvSpec>().is_err(), "{bad}");
        }
        assert_eq!(EnvSpec::default_for(true), EnvSpec::Constant([0.0; 3]));
        assert_eq!(EnvSpec::default_for(false), EnvSpec::Sky);
    }

    #[test]
    fn the_suns_radiance_gives_its_irradiance_face_on() {
        let sky = Sky::default();
        sky.check().unwrap();
        let r = sky.sun_radiance()[0];
        // Integrate the disc's radiance times cos over the disc numerically (face-on).
        let a = f64::from(sky.sun_radius_degrees).to_radians();
        let n = 100_000;
        let e: f64 = (0..n)
            .map(|i| {
                let th = (i as f64 + 0.5) / n as f64 * a;
                r * th.cos() * th.sin() * std::f64::consts::TAU * (a / n as f64)
            })
            .sum();
        assert!((e - f64::from(sky.sun_irradiance[0])).abs() < 1e-6 * e, "{e}");
        let up = sky.sun_irradiance_on(DVec3::Y)[0];
        assert!((up - f64::from(sky.sun_irradiance[0]) * sky.sun_dir_f64().y).abs() < 1e-12);
    }
}
