//! The UWB tags' lever arms (`mounting.lever_arm`): one antenna position in the body frame per
//! tag, tag 0 first.

use crate::config::parse::{vector, ToValue};
use crate::config::value::ConfigValue;
use crate::error::Result;
use crate::math::Vec3;
use crate::validate::invalid;

/// Most UWB tags one filter fuses.
pub const MAX_TAGS: usize = 4;

/// Each tag's antenna position in the body frame, m (the range model's `l`, Li & Wang 2020
/// eq. (33), one per tag): at least one, at most [`MAX_TAGS`], fixed-size (no allocation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeverArms {
    arms: [Vec3; MAX_TAGS],
    tags: usize,
}

impl LeverArms {
    /// One tag at `lever_arm`.
    pub fn one(lever_arm: Vec3) -> Self {
        let mut arms = [Vec3::zeros(); MAX_TAGS];
        arms[0] = lever_arm;
        Self { arms, tags: 1 }
    }

    /// Tag 0 at `first`, then `more` up to [`MAX_TAGS`] in all (the rest are left out: callers
    /// check the count first).
    pub fn with_more(first: Vec3, more: &[Vec3]) -> Self {
        let mut out = Self::one(first);
        for arm in more.iter().take(MAX_TAGS - 1) {
            out.arms[out.tags] = *arm;
            out.tags += 1;
        }
        out
    }

    /// The tags at `arms`, tag 0 first; fails without a tag or beyond [`MAX_TAGS`].
    pub fn new(arms: &[Vec3]) -> Result<Self> {
        if arms.is_empty() || arms.len() > MAX_TAGS {
            return Err(invalid(
                "mounting.lever_arm",
                format!("takes 1 to {MAX_TAGS} lever arms (one per tag), got {}", arms.len()),
            ));
        }
        let mut out = Self::one(arms[0]);
        out.arms[..arms.len()].copy_from_slice(arms);
        out.tags = arms.len();
        Ok(out)
    }

    /// Tag 0's lever arm (the only one of a single-tag rig).
    pub fn first(&self) -> &Vec3 {
        &self.arms[0]
    }

    /// Tag `tag`'s lever arm; tag 0's for a tag beyond those given (the inputs refuse such a
    /// tag before it gets here).
    pub fn of(&self, tag: usize) -> &Vec3 {
        self.as_slice().get(tag).unwrap_or(self.first())
    }

    /// Every tag's lever arm, tag 0 first.
    pub fn as_slice(&self) -> &[Vec3] {
        &self.arms[..self.tags]
    }

    /// How many tags.
    pub fn tags(&self) -> usize {
        self.tags
    }
}

impl Default for LeverArms {
    fn default() -> Self {
        Self::one(Vec3::zeros())
    }
}

impl ToValue for LeverArms {
    /// Three numbers per tag, tag 0 first.
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Vector(self.as_slice().iter().flat_map(|l| l.iter().copied()).collect()))
    }
}

/// Lever arms from three finite numbers per tag (`[x, y, z]` for one tag, `[x0, y0, z0, x1, y1,
/// z1, …]` or a list of `[x, y, z]` rows, flattened on the way in, for several).
pub fn lever_arms(field: &str, v: &ConfigValue) -> Result<LeverArms> {
    match v {
        ConfigValue::Vector(xs) if xs.len() > 3 && xs.len() % 3 == 0 => {
            let arms: Vec<Vec3> = xs
                .chunks_exact(3)
                .map(|c| vector::<3>(field, &ConfigValue::Vector(c.to_vec())).map(Vec3::from))
                .collect::<Result<_>>()?;
            LeverArms::new(&arms)
        }
        ConfigValue::Vector(xs) if xs.len() != 3 => Err(invalid(
            field,
            format!("expected 3 numbers per tag ([x, y, z], tag 0 first, up to {MAX_TAGS} tags), got {}: {xs:?}", xs.len()),
        )),
        _ => vector::<3>(field, v).map(|a| LeverArms::one(Vec3::from(a))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_or_several_tags_read_and_write_back() {
        let one = lever_arms("l", &ConfigValue::Vector(vec![0.1, 0.0, 0.2])).expect("one");
        assert_eq!((one.tags(), *one.first()), (1, Vec3::new(0.1, 0.0, 0.2)));
        let two = lever_arms("l", &ConfigValue::Vector(vec![0.5, 0.0, 0.1, -0.5, 0.0, 0.1])).expect("two");
        assert_eq!(two.as_slice(), &[Vec3::new(0.5, 0.0, 0.1), Vec3::new(-0.5, 0.0, 0.1)]);
        assert_eq!(lever_arms("l", &two.to_value().expect("value")).expect("again"), two);
        for bad in [vec![0.0; 2], vec![0.0; 4], vec![0.0; 15], vec![f64::NAN, 0.0, 0.0]] {
            assert!(lever_arms("l", &ConfigValue::Vector(bad)).is_err());
        }
    }
}
