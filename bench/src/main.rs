//! scratch
fn main() {
    use lagrangian_bench::methods::{Method, Setting};
    for p in lagrangian_bench::problem::all(1.0) {
        let t = std::time::Instant::now();
        let r = p.reference(p.horizon(), 1e-14);
        println!("{} {:?} {:.1}s", p.id(), r.as_ref().map(|r| (r.agreement, r.accepted)), t.elapsed().as_secs_f64());
        if let Ok(r) = r {
            for m in [Method::Midpoint, Method::Galerkin(4), Method::OdeSolversDop853, Method::DiffEqDop853, Method::DiffEqGauss6, Method::KahanLi8, Method::EnergyMidpoint] {
                let s = if m.adaptive() { Setting::Tolerance(1e-8) } else { Setting::Steps(p.coarsest_steps() * 20) };
                let run = p.run(m, s, p.horizon(), 0);
                let err = run.q.iter().zip(&r.q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                println!("  {:20} err {:.2e} {:.3}s {:?} {:?} {:?}", m.name(), err, run.seconds, run.failure, run.newton_per_step, run.evaluations);
            }
        }
    }
}
