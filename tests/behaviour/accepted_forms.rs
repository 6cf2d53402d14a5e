//! Forms of `#[lagrangian]` that look unusual but are accepted, and run.
//!
//! They were trybuild `pass` cases; as ordinary tests they compile with the
//! rest of this binary, and trybuild only has to check the misuses in
//! `ui-tests/tests/ui` (`cargo check`, no code generation for the dependencies).

/// `#[cfg]` on the whole block, one block per configuration: the trait
/// implementation follows the block that exists.
mod cfg_on_block {
    use lagrangian::prelude::*;

    pub struct Spring {
        pub k: f64,
    }

    #[lagrangian]
    #[cfg(debug_assertions)]
    impl Spring {
        fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
            0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
        }
    }

    #[lagrangian]
    #[cfg(not(debug_assertions))]
    impl Spring {
        fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
            0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
        }
    }

    #[test]
    fn runs() {
        let sim = Integrator::new(Spring { k: 4.0 }, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
        assert!((sim.energy().unwrap() - 2.0).abs() < 1e-12);
    }
}

/// A potential step acknowledged with `#[lagrangian(discontinuous)]`: it
/// compiles, and the trait says so.
mod discontinuous_acknowledged {
    use lagrangian::Lagrangian;
    use lagrangian::prelude::*;

    pub struct Step {
        pub h: f64,
    }

    #[lagrangian(discontinuous)]
    impl Step {
        fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
            let kinetic = 0.5 * v[0] * v[0];
            if q[0] > 0.0 { kinetic - self.h } else { kinetic }
        }
    }

    #[test]
    fn runs() {
        const { assert!(<Step as Lagrangian<1>>::DISCONTINUOUS) };
        let sim = Integrator::new(Step { h: 0.3 }, Midpoint, 0.01).start(0.0, [-1.0], [1.0]).unwrap();
        assert!((sim.energy().unwrap() - 0.5).abs() < 1e-12);
    }
}

/// `self: &Self` is `&self` written out; it is accepted, and the system runs.
// The form under test is the one clippy would rewrite.
#[allow(clippy::needless_arbitrary_self_type)]
mod receiver_self_ref_self {
    use lagrangian::prelude::*;

    pub struct Pendulum {
        pub m: f64,
    }

    #[lagrangian]
    impl Pendulum {
        fn lagrangian(self: &Self, q: [f64; 1], v: [f64; 1]) -> f64 {
            0.5 * self.m * v[0] * v[0] + q[0].cos()
        }
    }

    #[test]
    fn runs() {
        let mut sim = Integrator::new(Pendulum { m: 1.0 }, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
        sim.run(10, |_| {}).unwrap();
        assert!(sim.state().q[0] < 1.0);
    }
}

/// Run-time-sized forms: a generic block, `self: &Self`, a typed slice
/// local, `v.len()` bounds, a time argument and an acknowledged jump.
#[allow(clippy::needless_arbitrary_self_type)]
mod slices_run_time_sized {
    use lagrangian::prelude::*;

    pub struct Chain<T> {
        pub masses: Vec<f64>,
        pub tag: T,
    }

    #[lagrangian(discontinuous)]
    impl<T> Chain<T> {
        fn dimension(self: &Self) -> usize {
            self.masses.len()
        }

        fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
            let x: &[f64] = q;
            let mut l = 0.0;
            for i in 0..v.len() {
                l += 0.5 * self.masses[i] * v[i] * v[i];
            }
            for i in 1..x.len() {
                l -= (x[i] - x[i - 1]).powi(2);
            }
            if q[0] > 1.0 { l - t } else { l }
        }
    }

    #[test]
    fn runs() {
        let chain = Chain { masses: vec![1.0, 2.0], tag: () };
        let _ = &chain.tag;
        const { assert!(<Chain<()> as DynLagrangian>::DISCONTINUOUS && !<Chain<()> as DynLagrangian>::AUTONOMOUS) };
        let l = DynLagrangian::lagrangian(&chain, 0.5, &[0.0, 1.0], &[1.0, 1.0]);
        assert_eq!(l, 0.5 + 1.0 - 1.0);
        assert_eq!(DynLagrangian::dimension(&chain), 2);
        let l = DynLagrangian::lagrangian(&chain, 0.5, &[2.0, 2.0], &[0.0, 0.0]);
        assert_eq!(l, -0.5);
    }
}
