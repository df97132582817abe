//! The replay TOML file: `method = "..."`, a `[config]` table of [`FilterConfig`] keys (section
//! tables such as `[config.ranging]`, dotted keys, or the flat keys of earlier versions), an
//! optional `[initial]` table of [`InitialState`] keys (without it the filter initialises itself)
//! and a `[mapping]` table ([`Mapping`]). Relative
//! file paths in the mapping are resolved against the directory of the TOML file.

use std::path::Path;

use crate::io::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::config::{ConfigValue, FilterConfig, InitialState};
use uwbimu_vocabulary::error::Error as CoreError;

use crate::io::Mapping;
use crate::methods::{Method, DEFAULT_METHOD};

/// A parsed replay file.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayConfig {
    /// Method name, if given.
    pub method: Option<String>,
    /// Filter settings (defaults plus the `[config]` table).
    pub config: FilterConfig,
    /// Initial state (defaults plus the `[initial]` table; None without one: self-initialisation).
    pub initial: Option<InitialState>,
    /// Topic and field mapping.
    pub mapping: Mapping,
}

fn config_error(reason: impl Into<String>) -> Error {
    CoreError::InvalidConfig { field: "replay file".into(), reason: reason.into() }.into()
}

/// A TOML value as a [`ConfigValue`].
fn config_value(key: &str, v: &toml::Value) -> Result<ConfigValue> {
    let number = |x: &toml::Value| x.as_float().or_else(|| x.as_integer().map(|i| i as f64));
    match v {
        toml::Value::Boolean(b) => Ok(ConfigValue::Flag(*b)),
        toml::Value::Array(items) => items
            .iter()
            .map(|x| number(x).ok_or_else(|| config_error(format!("config `{key}`: expected numbers"))))
            .collect::<Result<Vec<f64>>>()
            .map(ConfigValue::Vector),
        other => number(other).map(ConfigValue::Scalar).ok_or_else(|| config_error(format!("config `{key}`: expected a number"))),
    }
}

impl ReplayConfig {
    /// The method to replay with: `given` (a command-line or call argument), else the file's
    /// `method`, else [`DEFAULT_METHOD`]. Fails on an unknown name.
    pub fn method_or(&self, given: Option<&str>) -> Result<Method> {
        Ok(Method::parse(given.or(self.method.as_deref()).unwrap_or(DEFAULT_METHOD.name()))?)
    }

    /// Parses TOML text; `base_dir` resolves relative anchor / ground-truth file paths.
    ///
    /// # Errors
    /// [`CoreError::InvalidConfig`] / [`CoreError::UnknownOption`] for bad filter settings or unknown
    /// top-level keys, [`Error::Mapping`] for a bad mapping table.
    pub fn from_toml(text: &str, base_dir: &Path) -> Result<Self> {
        let table: toml::Table = toml::from_str(text).map_err(|e| config_error(e.to_string()))?;
        let mut out = Self { method: None, config: FilterConfig::default(), initial: None, mapping: Mapping::default() };
        for (key, value) in table {
            match key.as_str() {
                "method" => {
                    out.method = Some(value.as_str().ok_or_else(|| config_error("`method` must be a string"))?.to_string())
                }
                "config" => {
                    let t = value.as_table().ok_or_else(|| config_error("`config` must be a table"))?;
                    for (k, v) in t {
                        match v.as_table() {
                            // A section table `[config.ranging]`: its keys are `ranging.<field>`.
                            Some(section) => {
                                for (field, fv) in section {
                                    let key = format!("{k}.{field}");
                                    out.config.set(&key, &config_value(&key, fv)?)?;
                                }
                            }
                            None => out.config.set(k, &config_value(k, v)?)?,
                        }
                    }
                }
                "initial" => {
                    let t = value.as_table().ok_or_else(|| config_error("`initial` must be a table"))?;
                    let initial = out.initial.get_or_insert_with(InitialState::default);
                    for (k, v) in t {
                        initial.set(k, &config_value(k, v)?)?;
                    }
                }
                "mapping" => {
                    out.mapping = value
                        .try_into()
                        .map_err(|e: toml::de::Error| Error::Mapping { field: "mapping".into(), reason: e.to_string() })?;
                }
                other => {
                    return Err(CoreError::UnknownOption {
                        kind: "replay file key",
                        got: other.into(),
                        allowed: "method, config, initial, mapping".into(),
                    }
                    .into())
                }
            }
        }
        for path in [&mut out.mapping.anchors.file, &mut out.mapping.ground_truth.file].into_iter().flatten() {
            if path.is_relative() {
                *path = base_dir.join(&*path);
            }
        }
        out.mapping = out.mapping.validate()?;
        Ok(out)
    }

    /// Reads and parses a replay file.
    ///
    /// # Errors
    /// [`Error::Io`] if unreadable; otherwise as [`ReplayConfig::from_toml`].
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path.display().to_string(), e))?;
        Self::from_toml(&text, path.parent().unwrap_or(Path::new(".")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_method_config_and_mapping() {
        let text = "method = \"riekf\"\n[config]\nranging.range_std = 0.2\nmounting.lever_arm = [0, 0, 0.1]\n[config.constraints]\nzupt = true\n\
                    [mapping]\nimu_topic = \"/imu\"\n[mapping.uwb]\ntopics = [\"/uwb\"]\nscale = 0.001\n[mapping.anchors]\nfile = \"a.csv\"\n";
        let c = ReplayConfig::from_toml(text, Path::new("/data")).unwrap();
        assert_eq!(c.method.as_deref(), Some("riekf"));
        assert_eq!(c.config.ranging.range_std, 0.2);
        assert!(c.config.constraints.zupt);
        assert_eq!(c.mapping.uwb.scale, Some(0.001));
        assert_eq!(c.mapping.anchors.file.as_deref(), Some(Path::new("/data/a.csv")));
        assert!(ReplayConfig::from_toml("[mapping]\nimu_topik = \"x\"\n", Path::new(".")).is_err());
        assert!(ReplayConfig::from_toml("[config]\nrange_sdt = 1\n", Path::new(".")).is_err());
        assert!(ReplayConfig::from_toml("metod = 1\n", Path::new(".")).is_err());
        let with_initial = "[initial]\nposition = [1, 2, 0.5]\norientation = [1, 0, 0, 0]\nposition_std = 0.2\n";
        let initial = ReplayConfig::from_toml(with_initial, Path::new(".")).unwrap().initial.unwrap();
        assert_eq!((initial.position.y, initial.position_std.z), (2.0, 0.2));
        assert!(c.initial.is_none());
        assert!(ReplayConfig::from_toml("[initial]\npositon = [1, 2, 3]\n", Path::new(".")).is_err());
    }
}
