//! The replay TOML file: `method = "..."`, a `[config]` table of [`FilterConfig`] keys (section
//! tables such as `[config.ranging]`, dotted keys, or the flat keys of earlier versions), an
//! optional `[initial]` table of [`InitialState`] keys (without it the filter initialises itself)
//! and a `[mapping]` table ([`Mapping`]). Relative
//! file paths in the mapping are resolved against the directory of the TOML file.

use std::path::Path;

use uwbimu_io::files::live_settings::LiveSettings;
use uwbimu_io::Mapping;
use uwbimu_io::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::config::{ConfigValue, FilterConfig, InitialState};
use uwbimu_vocabulary::error::Error as CoreError;

use crate::registry::{Method, DEFAULT_METHOD};

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
    /// The live node's settings (the `[live]` table).
    pub live: LiveSettings,
}

fn config_error(reason: impl Into<String>) -> Error {
    CoreError::InvalidConfig { field: "replay file".into(), reason: reason.into() }.into()
}

/// A TOML value as a [`ConfigValue`] (an array of equal-length arrays, such as one lever arm
/// per tag, read row after row); the error is why it is not one (the caller names the key).
fn config_value(v: &toml::Value) -> std::result::Result<ConfigValue, String> {
    let number = |x: &toml::Value| x.as_float().or_else(|| x.as_integer().map(|i| i as f64));
    let numbers = |items: &[toml::Value]| items.iter().map(number).collect::<Option<Vec<f64>>>();
    let wrong = || format!("expected a number, true/false or an array of numbers, got {v}");
    match v {
        toml::Value::Boolean(b) => Ok(ConfigValue::Flag(*b)),
        toml::Value::Array(items) => match numbers(items) {
            Some(xs) => Ok(ConfigValue::Vector(xs)),
            None => {
                let rows = items.iter().map(|r| r.as_array().and_then(|r| numbers(r))).collect::<Option<Vec<_>>>();
                rows.filter(|rows| rows.windows(2).all(|w| w[0].len() == w[1].len()))
                    .map(|rows| ConfigValue::Vector(rows.concat()))
                    .ok_or_else(wrong)
            }
        },
        other => number(other).map(ConfigValue::Scalar).ok_or_else(wrong),
    }
}

/// Sets the `[config]` key `key` (`section.field`) from its TOML value.
fn set_config(config: &mut FilterConfig, key: &str, v: &toml::Value) -> Result<()> {
    FilterConfig::check_key(key)?;
    let value = config_value(v).map_err(|reason| CoreError::InvalidConfig { field: key.to_string(), reason })?;
    Ok(config.set(key, &value)?)
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
        let mut out = Self {
            method: None,
            config: FilterConfig::default(),
            initial: None,
            mapping: Mapping::default(),
            live: LiveSettings::default(),
        };
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
                                    set_config(&mut out.config, &format!("{k}.{field}"), fv)?;
                                }
                            }
                            None => set_config(&mut out.config, k, v)?,
                        }
                    }
                }
                "initial" => {
                    let t = value.as_table().ok_or_else(|| config_error("`initial` must be a table"))?;
                    let initial = out.initial.get_or_insert_with(InitialState::default);
                    for (k, v) in t {
                        let value = config_value(v)
                            .map_err(|reason| CoreError::InvalidInitial { key: format!("initial.{k}"), reason })?;
                        initial.set(k, &value)?;
                    }
                }
                "mapping" => {
                    let tree = serde_json::to_value(value)
                        .map_err(|e| Error::Mapping { field: String::new(), reason: e.to_string() })?;
                    out.mapping = Mapping::from_value(tree)?;
                }
                "live" => {
                    let tree = serde_json::to_value(value)
                        .map_err(|e| Error::Mapping { field: "live".into(), reason: e.to_string() })?;
                    out.live = LiveSettings::from_value(tree)?;
                }
                other => {
                    return Err(CoreError::unknown_option(
                        "replay file key",
                        other,
                        ["method", "config", "initial", "mapping", "live"],
                    )
                    .into())
                }
            }
        }
        let files = [&mut out.mapping.anchors.file, &mut out.mapping.ground_truth.file].into_iter().flatten();
        for path in files.chain(out.live.msg_paths.iter_mut()) {
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
            .map_err(|e| Error::InFile { path: path.display().to_string(), source: Box::new(e) })
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

    #[test]
    fn errors_name_the_file_and_the_key() {
        let dir = std::env::temp_dir().join(format!("uwbimu-replay-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.toml");
        for (text, expected) in [
            ("[mapping]\nimu_topc = \"/imu\"\n", "`mapping.imu_topc`: unknown key (did you mean `imu_topic`?)"),
            ("[config]\nranging.range_std = \"0.2\"\n", "config `ranging.range_std`: expected a number"),
            ("[initial]\norientation = [0, 0, 0, 0]\n", "initial state `initial.orientation`: quaternion"),
        ] {
            std::fs::write(&path, text).unwrap();
            let e = ReplayConfig::read(&path).unwrap_err().to_string();
            assert!(e.starts_with(&format!("{}: {expected}", path.display())), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
