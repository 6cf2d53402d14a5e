//! The scratch of an energy-preserving Galerkin step's trial steps on the
//! tape: held by the Galerkin work (`galerkin.rs`), filled by the energy
//! probes (`galerkin_energy.rs`), a file of its own so that neither names
//! the other both ways.

/// The trial steps of an energy-preserving step: the latest probe's
/// nodes and their tangent, scratch that a copy does not share.
#[derive(Debug, Default)]
pub(crate) struct NodeProbes {
    /// The size of the latest solved probe (`None`: none since the last
    /// step taken).
    pub(super) h: Option<f64>,
    /// Its unknowns `D`, in the unknowns' order.
    pub(super) nodes: Vec<f64>,
    /// `dD/dh = −J⁻¹b` there (valid where its slope is finite).
    pub(super) tangent: Vec<f64>,
}

impl Clone for NodeProbes {
    fn clone(&self) -> Self {
        Self::default()
    }

    /// Scratch: nothing to copy.
    fn clone_from(&mut self, _: &Self) {}
}
