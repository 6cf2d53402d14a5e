//! The method families of the one-way-in matrix, as [`Scheme`] values: the
//! behaviour matrix steps each of them and the capability page lists what
//! [`lagrangian::problem::supports`] says of each.

use lagrangian::prelude::*;

/// `(name, scheme, needs a separable system)` for every family.
pub fn families() -> Vec<(&'static str, Scheme, bool)> {
    let curvature = Curvature::new(1.0).unwrap();
    vec![
        ("midpoint", Scheme::MIDPOINT, false),
        ("trapezoid", Scheme::TRAPEZOID, false),
        ("α-β (α = 0.5)", Scheme::alpha_beta(0.5).unwrap(), false),
        ("Galerkin s = 2", Scheme::galerkin(2), false),
        ("Galerkin s = 3", Scheme::galerkin(3), false),
        ("Galerkin s = 4", Scheme::galerkin(4), false),
        ("Yoshida 4", Scheme::composition(Composition::YOSHIDA4, OnePoint::Trapezoid), false),
        ("Yoshida 6", Scheme::composition(Composition::YOSHIDA6, OnePoint::Trapezoid), false),
        ("Kahan–Li 8", Scheme::composition(Composition::KAHAN_LI8, OnePoint::Trapezoid), false),
        ("time-transformed midpoint", Scheme::MIDPOINT.time_transformed(curvature), false),
        ("time-transformed Galerkin s = 2", Scheme::galerkin(2).time_transformed(curvature), false),
        (
            "explicit time-transformed Kahan–Li 8",
            Scheme::splitting(TimeFunction::Logarithmic, Some(Composition::KAHAN_LI8)),
            true,
        ),
        ("Yoshida 6 of midpoint", Scheme::MIDPOINT.composed(Composition::YOSHIDA6), false),
        ("Yoshida 4 of Galerkin s = 2", Scheme::galerkin(2).composed(Composition::YOSHIDA4), false),
    ]
}
