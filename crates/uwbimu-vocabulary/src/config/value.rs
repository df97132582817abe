//! One configuration value as it arrives from a dict or a TOML table ([`ConfigValue`]): below the
//! sections and their parsers, so that a section may be declared beside what it configures (a
//! sensor's, in its own module) without an import circle.

/// A configuration value as it arrives from a dict: a scalar or a vector.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigValue {
    /// A single number.
    Scalar(f64),
    /// A sequence of numbers.
    Vector(Vec<f64>),
    /// A switch.
    Flag(bool),
}
