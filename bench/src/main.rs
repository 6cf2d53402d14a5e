//! `lagrangian-bench`: runs the work–precision and stress suite and writes
//! the report (see `--help`).

use std::path::PathBuf;
use std::process::ExitCode;

use lagrangian_bench::methods::Method;
use lagrangian_bench::suite::{self, Config, Suite};
use lagrangian_bench::{output, readme};

const HELP: &str = "\
lagrangian-bench: work–precision and stress report of the lagrangian integrators

USAGE:
    cargo run --release -p lagrangian-bench -- [OPTIONS]
    cargo run --release -p lagrangian-bench -- readme [--from FILE] [--readme FILE].. [--section NAME[,NAME..]]

Without options: the default suite, one problem of each family at a fifth of its
horizon, two targets, every method and peer crate, the stress section at 10⁵
steps (70 s of CPU time on one thread on a 2-core machine at a load average of 3);
a progress line on stderr as each problem and method starts, the headline table
and the report's path at the end.

OPTIONS:
    --full                   every problem at its own horizon, three targets, energy runs over
                             100 horizons, 10⁷-step runs (about 9 minutes on 2 cores)
    --exhaustive             ten targets, larger time budgets, energy runs over 1000 horizons
    --tiny                   smallest sizes (for the test suite)
    --problem ID[,ID..]      only these problems (repeatable)
    --method NAME[,NAME..]   only these methods (repeatable)
    --out DIR                output directory (default target/report)
    --scale X                multiply every problem's horizon by X (e.g. `--problem pendulum --scale 20`:
                             1000 periods; `--problem kepler-0.9 --scale 100`: 1000 orbits)
    --targets E[,E..]        target errors in place of the suite's
    --calibration-only       only the work–precision calibration (no long energy runs, stress section
                             or step costs)
    --reference-tolerance X  relative agreement a reference must reach (default 1e-14)
    --no-progress            no progress lines
    --list                   list problems and methods
    -h, --help               this text

readme: rewrites the generated performance tables from a report's JSON
(default target/report/report.json; pages README.md and docs/measurements.md,
or each --readme FILE): each section between
`<!-- bench:NAME:begin -->` and `<!-- bench:NAME:end -->` markers, NAME one of
headline, step-cost, galerkin-step-cost, compositions, time-transformed (from a report
of the suite's own horizons), calibrated-ID (every method's calibrated run on problem
ID), calibrated-ID-xK (the same from a report run with `--scale K`) or constraints-ID
(the constraint and energy drift of each calibrated run on problem ID, a problem with
constraints) (--section: only these). A section the report cannot supply is left as it is.
";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // Double-double Galerkin references on 18 degrees of freedom keep large blocks on the stack.
    let worker = std::thread::Builder::new().stack_size(256 << 20).spawn(move || run(args));
    let result = match worker.map(|w| w.join()) {
        Ok(Ok(result)) => result,
        Ok(Err(_)) => Err("the report panicked (a bug: please report it)".to_string()),
        Err(e) => Err(format!("cannot start the worker thread: {e}")),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn values(args: &mut impl Iterator<Item = String>, flag: &str) -> Result<Vec<String>, String> {
    let v = args.next().ok_or_else(|| format!("`{flag}` needs a value"))?;
    Ok(v.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect())
}

/// The command line that runs `args`, to state in the report. `--out DIR`
/// is left out: where the report is written does not change what it
/// measures, and a reader's machine has no such directory.
fn command(args: &[String]) -> String {
    let mut kept = Vec::with_capacity(args.len());
    let mut rest = args.iter();
    while let Some(a) = rest.next() {
        if a == "--out" {
            rest.next();
        } else {
            kept.push(a);
        }
    }
    let mut c = String::from("cargo run --release -p lagrangian-bench");
    if !kept.is_empty() {
        c.push_str(" --");
    }
    for a in kept {
        let plain = !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_.,/=+:".contains(c));
        c.push(' ');
        if plain {
            c.push_str(a);
        } else {
            c.push_str(&format!("'{}'", a.replace('\'', r"'\''")));
        }
    }
    c
}

fn run(args: Vec<String>) -> Result<(), String> {
    let command = command(&args);
    let mut args = args.into_iter();
    let mut suite = Suite::Default;
    let mut problems: Option<Vec<String>> = None;
    let mut methods: Option<Vec<Method>> = None;
    let mut out = PathBuf::from("target/report");
    let mut reference_tolerance = 1e-14;
    let mut progress = true;
    let mut readme_mode = false;
    let mut from = PathBuf::from("target/report/report.json");
    let mut readme_paths: Vec<PathBuf> = Vec::new();
    let mut sections: Vec<String> = Vec::new();
    let mut horizon_scale = 1.0;
    let mut targets: Option<Vec<f64>> = None;
    let mut calibration_only = false;
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "readme" => readme_mode = true,
            "--from" => from = PathBuf::from(args.next().ok_or("`--from` needs a file")?),
            "--section" => sections.extend(values(&mut args, "--section")?),
            "--readme" => readme_paths.push(PathBuf::from(args.next().ok_or("`--readme` needs a file")?)),
            "--full" => suite = Suite::Full,
            "--exhaustive" => suite = Suite::Exhaustive,
            "--tiny" => suite = Suite::Tiny,
            "--no-progress" => progress = false,
            "--calibration-only" => calibration_only = true,
            "--scale" => {
                let v = args.next().ok_or("`--scale` needs a number")?;
                horizon_scale = v
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite() && *x > 0.0)
                    .ok_or_else(|| format!("`--scale`: `{v}` is not a positive number"))?;
            }
            "--targets" => {
                let mut list = Vec::new();
                for v in values(&mut args, "--targets")? {
                    let x = v
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite() && *x > 0.0)
                        .ok_or_else(|| format!("`--targets`: `{v}` is not a positive number"))?;
                    list.push(x);
                }
                if list.is_empty() {
                    return Err("`--targets` needs at least one error".into());
                }
                targets = Some(list);
            }
            "--out" => out = PathBuf::from(args.next().ok_or("`--out` needs a directory")?),
            "--reference-tolerance" => {
                let v = args.next().ok_or("`--reference-tolerance` needs a number")?;
                reference_tolerance =
                    v.parse().map_err(|_| format!("`--reference-tolerance`: `{v}` is not a number"))?;
            }
            "--problem" => {
                let known = suite::problem_ids();
                for id in values(&mut args, "--problem")? {
                    if !known.contains(&id.as_str()) {
                        return Err(format!("unknown problem `{id}` (known: {})", known.join(", ")));
                    }
                    problems.get_or_insert_with(Vec::new).push(id);
                }
            }
            "--method" => {
                for name in values(&mut args, "--method")? {
                    let m = Method::parse(&name).ok_or_else(|| {
                        let known: Vec<String> = Method::all().iter().map(|m| m.name()).collect();
                        format!("unknown method `{name}` (known: {})", known.join(", "))
                    })?;
                    methods.get_or_insert_with(Vec::new).push(m);
                }
            }
            "--list" => {
                println!("problems: {}", suite::problem_ids().join(", "));
                println!("problems of the default suite: {}", suite::DEFAULT_PROBLEMS.join(", "));
                let known: Vec<String> = Method::all().iter().map(|m| m.name()).collect();
                println!("methods: {}", known.join(", "));
                return Ok(());
            }
            "-h" | "--help" => {
                print!("{HELP}");
                return Ok(());
            }
            other => return Err(format!("unknown argument `{other}` (see --help)")),
        }
    }
    if readme_mode {
        if readme_paths.is_empty() {
            readme_paths = readme::PAGES.iter().map(PathBuf::from).collect();
        }
        return readme::update_pages(&from, &readme_paths, &sections);
    }
    let config = Config {
        suite,
        problems,
        methods,
        reference_tolerance,
        progress,
        horizon_scale,
        targets,
        calibration_only,
        command,
    };
    let start = std::time::Instant::now();
    let report = suite::run(&config)?;
    output::write(&report, &out)?;
    println!("Fastest method of each kind per problem and target (suite `{}`):\n", report.suite);
    print!("{}", output::headline(&report, &report.targets));
    println!(
        "\nreport: {} (also report.html, report.json and the plots in {}); {:.0} s",
        out.join("report.md").display(),
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::command;

    #[test]
    fn the_stated_command_leaves_out_the_output_directory() {
        let args: Vec<String> = ["--full", "--out", "/tmp/x", "--method", "auto,galerkin-4"].map(String::from).into();
        assert_eq!(command(&args), "cargo run --release -p lagrangian-bench -- --full --method auto,galerkin-4");
        let args: Vec<String> = ["--out", "/tmp/x"].map(String::from).into();
        assert_eq!(command(&args), "cargo run --release -p lagrangian-bench");
    }
}
