//! The inertial filter types by name ([`InertialKind`]) and the one `match` from a name to its
//! type ([`InertialKind::visit`]): what runs a method generically over its filter (the batch
//! runner, the streamed replay) says what to do with the type in an [`InertialVisitor`].

use crate::filters::{Ackf, Arckf, Best, Ckf, Criekf, Ekf, Eskf, Iekf, NamedFilter, Rekf, Riekf, Rukf, Shaf, Shfaf, Ukf};

/// What to do with the filter type an [`InertialKind`] names ([`InertialKind::visit`]).
pub trait InertialVisitor {
    /// What the visit returns.
    type Output;

    /// Does it with the filter type `F`.
    fn visit<F: NamedFilter>(self) -> Self::Output;
}

/// One variant per inertial filter type of a method of the registry (`uwbimu_app::registry`),
/// named as the type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InertialKind {
    /// [`Ekf`].
    Ekf,
    /// [`Iekf`].
    Iekf,
    /// [`Rekf`].
    Rekf,
    /// [`Riekf`].
    Riekf,
    /// [`Criekf`].
    Criekf,
    /// [`Ckf`].
    Ckf,
    /// [`Arckf`].
    Arckf,
    /// [`Ackf`].
    Ackf,
    /// [`Eskf`].
    Eskf,
    /// [`Shaf`].
    Shaf,
    /// [`Shfaf`].
    Shfaf,
    /// [`Ukf`].
    Ukf,
    /// [`Rukf`].
    Rukf,
    /// [`Best`].
    Best,
}

impl InertialKind {
    /// Every kind, in the order of the registry's rows.
    pub const ALL: [InertialKind; 14] = [
        Self::Ekf,
        Self::Iekf,
        Self::Rekf,
        Self::Riekf,
        Self::Criekf,
        Self::Ckf,
        Self::Arckf,
        Self::Ackf,
        Self::Eskf,
        Self::Shaf,
        Self::Shfaf,
        Self::Ukf,
        Self::Rukf,
        Self::Best,
    ];

    /// Calls `visitor` with the filter type this kind names.
    pub fn visit<V: InertialVisitor>(self, visitor: V) -> V::Output {
        match self {
            Self::Ekf => visitor.visit::<Ekf>(),
            Self::Iekf => visitor.visit::<Iekf>(),
            Self::Rekf => visitor.visit::<Rekf>(),
            Self::Riekf => visitor.visit::<Riekf>(),
            Self::Criekf => visitor.visit::<Criekf>(),
            Self::Ckf => visitor.visit::<Ckf>(),
            Self::Arckf => visitor.visit::<Arckf>(),
            Self::Ackf => visitor.visit::<Ackf>(),
            Self::Eskf => visitor.visit::<Eskf>(),
            Self::Shaf => visitor.visit::<Shaf>(),
            Self::Shfaf => visitor.visit::<Shfaf>(),
            Self::Ukf => visitor.visit::<Ukf>(),
            Self::Rukf => visitor.visit::<Rukf>(),
            Self::Best => visitor.visit::<Best>(),
        }
    }

    /// The name of the filter type ([`NamedFilter::NAME`]), which is also its Python streaming
    /// class's.
    pub fn type_name(self) -> &'static str {
        self.visit(TypeName)
    }
}

/// The visit that returns the type's name.
struct TypeName;

impl InertialVisitor for TypeName {
    type Output = &'static str;

    fn visit<F: NamedFilter>(self) -> &'static str {
        F::NAME
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_names_its_own_type() {
        for kind in InertialKind::ALL {
            assert_eq!(kind.type_name(), format!("{kind:?}"));
        }
    }
}
