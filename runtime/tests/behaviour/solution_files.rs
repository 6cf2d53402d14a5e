//! Solutions on disk: the CSV and JSON writers refuse solutions whose
//! columns differ in length, the readers refuse what is not the table of a
//! solution (typed errors with row and column; the number of coordinates
//! comes from the table), and
//! every `f64` (±0, subnormals, ±∞, NaN with its sign and payload)
//! round-trips bit for bit in both formats.

use lagrangian_runtime::solution::{EnergyWatch, RunStats, Status, TableError};
use lagrangian_runtime::{EventRecord, Integrator, Lagrangian, Midpoint, Rows, Scalar, Solution, Stepping};

/// A solution of `N` coordinates from its columns, without events.
fn table<const N: usize>(
    t: Vec<f64>,
    step: Vec<Option<u64>>,
    q: Vec<[f64; N]>,
    p: Vec<[f64; N]>,
    v: Vec<[f64; N]>,
    energy: Vec<f64>,
) -> Solution {
    Solution {
        t,
        step,
        q: Rows::from_rows(q).unwrap(),
        p: Rows::from_rows(p).unwrap(),
        v: Rows::from_rows(v).unwrap(),
        energy,
        events: Vec::new(),
        stats: RunStats::default(),
        energy_watch: None,
        status: Status::Finished,
        error: None,
    }
}

/// Three rows of an `N = 1` solution with velocities.
fn three_rows() -> Solution {
    table(
        vec![0.0, 0.5, 1.0],
        vec![Some(0), None, Some(1)],
        vec![[1.0], [0.875], [0.5]],
        vec![[0.0], [-0.5], [-0.75]],
        vec![[0.0], [-0.5], [-0.75]],
        vec![0.5, 0.5, 0.40625],
    )
}

/// The JSON of an `N = 1` solution from the texts of its columns.
fn json(t: &str, step: &str, q: &str, p: &str, v: &str, energy: &str) -> String {
    format!(
        concat!(
            r#"{{"t":{t},"step":{step},"q":{q},"p":{p},"v":{v},"energy":{energy},"events":[],"#,
            r#""stats":{{"steps":0,"newton_iterations":0,"failed_steps":0,"redone_steps":0,"#,
            r#""velocity_solves":0,"event_evaluations":0}},"energy_watch":null,"status":"Finished"}}"#
        ),
        t = t,
        step = step,
        q = q,
        p = p,
        v = v,
        energy = energy
    )
}

/// The columns of [`three_rows`] as JSON texts.
const T: &str = "[0.0,0.5,1.0]";
const STEP: &str = "[0,null,1]";
const Q: &str = "[[1.0],[0.875],[0.5]]";
const P: &str = "[[0.0],[-0.5],[-0.75]]";
const ENERGY: &str = "[0.5,0.5,0.40625]";

fn length_error(e: TableError) -> (&'static str, usize, &'static str, usize) {
    match e {
        TableError::Length { column, rows, reference, expected } => (column, rows, reference, expected),
        e => panic!("expected a length error, got {e:?}"),
    }
}

/// The template reads back what the writer writes, so that the refusals
/// below come from the lengths and nothing else.
#[test]
fn the_json_template_is_what_write_json_writes() {
    let mut out = Vec::new();
    three_rows().write_json(&mut out).unwrap();
    assert_eq!(String::from_utf8(out).unwrap(), json(T, STEP, Q, P, P, ENERGY));
    assert_eq!(Solution::read_json(json(T, STEP, Q, P, P, ENERGY).as_bytes()).unwrap(), three_rows());
}

#[test]
fn read_json_refuses_columns_of_unequal_length() {
    let read = |text: String| length_error(Solution::read_json(text.as_bytes()).unwrap_err());
    // `t` one row longer than `q` (and `p`).
    let long_t = "[0.0,0.5,1.0,1.5]";
    assert_eq!(read(json(long_t, "[0,null,1,2]", Q, P, P, ENERGY)), ("q", 3, "t", 4));
    // `step` shorter than `t`.
    assert_eq!(read(json(T, "[0,null]", Q, P, P, ENERGY)), ("step", 2, "t", 3));
    // `p` longer than `t`.
    assert_eq!(read(json(T, STEP, Q, "[[0.0],[-0.5],[-0.75],[1.0]]", P, ENERGY)), ("p", 4, "t", 3));
    // `energy` empty while `v` is full, and the other way round.
    assert_eq!(read(json(T, STEP, Q, P, P, "[]")), ("energy", 0, "v", 3));
    assert_eq!(read(json(T, STEP, Q, P, "[]", ENERGY)), ("energy", 3, "v", 0));
    // `v` neither empty nor one per row.
    assert_eq!(read(json(T, STEP, Q, P, "[[0.0]]", "[0.5]")), ("v", 1, "t", 3));
    let e = Solution::read_json(json(T, "[0,null]", Q, P, P, ENERGY).as_bytes()).unwrap_err();
    assert_eq!(e.to_string(), "column `step` has 2 rows, `t` has 3");
}

/// Hand-built solutions with the reported inconsistencies: both writers
/// refuse them before writing anything, and do not panic.
#[test]
fn the_writers_refuse_columns_of_unequal_length() {
    let mut long_t = three_rows();
    long_t.t.push(1.5);
    let mut short_step = three_rows();
    short_step.step.pop();
    let mut no_energy = three_rows();
    no_energy.energy.clear();
    let mut no_v = three_rows();
    no_v.v = Rows::new(1);
    let mut short_v = three_rows();
    short_v.v.truncate(2);
    short_v.energy.pop();
    let cases = [
        (long_t, ("step", 3, "t", 4)),
        (short_step, ("step", 2, "t", 3)),
        (no_energy, ("energy", 0, "v", 3)),
        (no_v, ("energy", 3, "v", 0)),
        (short_v, ("v", 2, "t", 3)),
    ];
    for (sol, expected) in cases {
        let mut out = Vec::new();
        assert_eq!(length_error(sol.write_csv(&mut out).unwrap_err()), expected);
        assert!(out.is_empty(), "nothing is written");
        assert_eq!(length_error(sol.write_json(&mut out).unwrap_err()), expected);
        assert!(out.is_empty(), "nothing is written");
    }
}

/// The values that a run can produce and a text format can lose.
fn awkward_values() -> Vec<f64> {
    vec![
        0.0,
        -0.0,
        f64::from_bits(1),                      // the smallest subnormal
        -f64::from_bits(0x000f_ffff_ffff_ffff), // the largest subnormal, negative
        f64::MIN_POSITIVE,
        f64::MAX,
        -f64::MAX,
        0.1,
        1.0 / 3.0,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
        -f64::NAN,
        f64::from_bits(0x7ff0_0000_0000_0001), // a signalling NaN
        f64::from_bits(0xfff4_0000_0000_00ab), // a negative NaN with a payload
        f64::from_bits(0x7fff_ffff_ffff_ffff),
    ]
}

/// A solution of two coordinates whose every `f64` is one of
/// [`awkward_values`] (each value in each column).
fn awkward() -> Solution {
    let x = awkward_values();
    let n = x.len();
    let at = |i: usize| x[i % n];
    let rows = |k: usize| (0..n).map(|i| [at(i + k), at(i + k + 1)]).collect::<Vec<_>>();
    let mut sol = table(
        x.clone(),
        (0..n).map(|i| if i % 3 == 1 { None } else { Some(i as u64 * 7) }).collect(),
        rows(1),
        rows(3),
        rows(5),
        (0..n).map(|i| at(i + 7)).collect(),
    );
    // Event times are finite (a root between two finite times); `EventRecord::t` has no
    // text for non-finite values.
    let event_t = |i: usize| if i == 0 { -0.0 } else { i as f64 / 3.0 };
    sol.events = (0..n)
        .map(|i| EventRecord {
            event: i,
            t: event_t(i),
            q: vec![at(i + 2), at(i + 4)],
            v: vec![at(i + 6), at(i + 8)],
            rising: i % 2 == 0,
        })
        .collect();
    sol.energy_watch = Some(EnergyWatch {
        tolerance: 1e-3,
        initial: f64::NEG_INFINITY,
        largest: -f64::NAN,
        largest_at: -0.0,
        exceeded_at: Some(f64::from_bits(1)),
    });
    sol.status = Status::Stopped { event: 3, t: -0.0 };
    sol
}

/// Every value of the columns as bits.
fn column_bits(sol: &Solution) -> Vec<Vec<u64>> {
    let flat = |rows: &Rows| rows.iter().flatten().map(|x| x.to_bits()).collect();
    vec![
        sol.t.iter().map(|x| x.to_bits()).collect(),
        flat(&sol.q),
        flat(&sol.p),
        flat(&sol.v),
        sol.energy.iter().map(|x| x.to_bits()).collect(),
    ]
}

/// Everything else that holds an `f64`, as bits.
fn other_bits(sol: &Solution) -> Vec<u64> {
    let mut bits = Vec::new();
    for e in &sol.events {
        bits.extend([e.t, e.q[0], e.q[1], e.v[0], e.v[1]].map(f64::to_bits));
    }
    if let Some(w) = sol.energy_watch {
        bits.extend([w.tolerance, w.initial, w.largest, w.largest_at].map(f64::to_bits));
        bits.extend(w.exceeded_at.map(f64::to_bits));
    }
    if let Status::Stopped { t, .. } = sol.status {
        bits.push(t.to_bits());
    }
    bits
}

#[test]
fn csv_round_trips_every_value_bit_for_bit() {
    let sol = awkward();
    let mut out = Vec::new();
    sol.write_csv(&mut out).unwrap();
    let text = String::from_utf8(out.clone()).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "t,step,q0,q1,p0,p1,v0,v1,energy");
    assert_eq!(lines.len(), 1 + sol.len());
    // The `t` column, one value per row, in the documented texts.
    let t: Vec<&str> = lines[1..].iter().map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(
        &t[9..],
        ["inf", "-inf", "NaN", "-NaN", "NaN:0x7ff0000000000001", "NaN:0xfff40000000000ab", "NaN:0x7fffffffffffffff"]
    );
    assert_eq!(&t[..2], ["0.0", "-0.0"]);

    let back = Solution::read_csv(out.as_slice()).unwrap();
    assert_eq!(column_bits(&back), column_bits(&sol));
    assert_eq!(back.step, sol.step);
}

#[test]
fn json_round_trips_every_value_bit_for_bit() {
    let sol = awkward();
    let mut out = Vec::new();
    sol.write_json(&mut out).unwrap();
    let text = String::from_utf8(out.clone()).unwrap();
    // The interpolated rows' steps are the only nulls.
    let interpolated = sol.step.iter().filter(|s| s.is_none()).count();
    assert_eq!(text.matches("null").count(), interpolated, "no value is written as null: {text}");
    assert!(text.starts_with(r#"{"t":[0.0,-0.0,5e-324,"#), "{}", &text[..40]);
    assert!(text.contains(r#""inf","-inf","NaN","-NaN","NaN:0x7ff0000000000001","NaN:0xfff40000000000ab""#));

    let back = Solution::read_json(out.as_slice()).unwrap();
    assert_eq!(column_bits(&back), column_bits(&sol));
    assert_eq!(other_bits(&back), other_bits(&sol));
    assert_eq!(back.step, sol.step);
    let tags = |s: &Solution| s.events.iter().map(|e| (e.event, e.rising)).collect::<Vec<_>>();
    assert_eq!(tags(&back), tags(&sol));
    assert!(matches!(back.status, Status::Stopped { event: 3, .. }));
}

/// `L = ½v² + ½q²`: solutions grow as `e^t`, and `E_L = ½v² − ½q²` is
/// `∞ − ∞` once `v²` and `q²` overflow.
#[derive(Clone)]
struct Repulsive;
impl Lagrangian<1> for Repulsive {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        (v[0] * v[0] + q[0] * q[0]) * 0.5
    }
}

/// A run that ends where `L = ½(v² + q²)` overflows: the step there is a
/// typed error, and the partial solution, its failed status included,
/// round-trips bit for bit (non-finite values: the `…_round_trips_every_value_bit_for_bit` tests).
#[test]
fn a_run_stopped_by_an_overflowing_lagrangian_round_trips() {
    let mut sim = Integrator::new(Repulsive, Midpoint, 0.01).start(0.0, [1e153], [1e153]).unwrap();
    let sol = sim.solve(lagrangian_runtime::Plan::until(3.0).every(10)).unwrap();
    assert!(matches!(sol.status, Status::Failed { .. }), "{:?}", sol.status);
    assert!(sol.len() > 1 && sol.q.iter().all(|q| q[0].is_finite()));

    let mut json = Vec::new();
    sol.write_json(&mut json).unwrap();
    let back = Solution::read_json(json.as_slice()).unwrap();
    assert_eq!(column_bits(&back), column_bits(&sol));
    let mut csv = Vec::new();
    sol.write_csv(&mut csv).unwrap();
    let back = Solution::read_csv(csv.as_slice()).unwrap();
    assert_eq!(column_bits(&back), column_bits(&sol));
}

fn csv_error(text: &str) -> TableError {
    Solution::read_csv(text.as_bytes()).unwrap_err()
}

/// The CSV of an `N = 1` solution with velocities has as many columns as
/// that of an `N = 2` solution without: the last column's name tells them
/// apart, and the others must then be those of that layout.
#[test]
fn read_csv_checks_the_header_names() {
    let mut out = Vec::new();
    three_rows().write_csv(&mut out).unwrap();
    assert!(out.starts_with(b"t,step,q0,p0,v0,energy\n"));
    assert_eq!(Solution::read_csv(out.as_slice()).unwrap(), three_rows());
    match csv_error("t,step,q0,p0,v0,e\n") {
        TableError::Header { column, found, expected } => {
            assert_eq!((column, found.as_str(), expected.as_str()), (3, "p0", "q1"));
        }
        e => panic!("{e:?}"),
    }

    match csv_error("a,b,c,d\n1,2,3,4\n") {
        TableError::Header { column, found, expected } => {
            assert_eq!((column, found, expected), (0, "a".into(), "t".into()))
        }
        e => panic!("{e:?}"),
    }
    // Nine columns fit only `N = 2` with velocities.
    let e = csv_error("t,step,q0,q1,p0,p1,v0,v1,E\n");
    assert_eq!(e.to_string(), "csv: header column 8 is `E`, expected `energy`");
    match csv_error("t,step,q0,p0,x\n") {
        TableError::Columns { found } => assert_eq!(found, 5),
        e => panic!("{e:?}"),
    }
    assert!(matches!(csv_error(""), TableError::Columns { found: 0 }));
}

#[test]
fn read_csv_names_the_row_and_column_of_a_bad_field() {
    let value = |e: TableError| match e {
        TableError::Value { row, column, text, expected } => (row, column, text, expected),
        e => panic!("expected a value error, got {e:?}"),
    };
    let head = "t,step,q0,p0\n0.0,0,1.0,0.0\n";
    assert_eq!(value(csv_error(&format!("{head}0.5,,abc,0.0\n"))), (1, "q0".into(), "abc".into(), "a number"));
    // Other spellings of NaN and infinity, and numbers that overflow, are not the documented texts.
    for text in ["nan", "NAN", "+NaN", "infinity", "Inf", "1e400", "NaN:0x7ff0000000000000", "NaN:0x7ff8", ""] {
        assert_eq!(value(csv_error(&format!("{head}0.5,,1.0,{text}\n"))), (1, "p0".into(), text.into(), "a number"));
    }
    for text in ["-1", "1.0", "x", " 1"] {
        let e = value(csv_error(&format!("{head}0.5,{text},1.0,0.0\n")));
        assert_eq!(e, (1, "step".into(), text.into(), "a node index or empty"));
    }
    let e = csv_error(&format!("{head}0.5,,abc,0.0\n"));
    assert_eq!(e.to_string(), "csv: row 1, column `q0`: `abc` is not a number");
    match csv_error(&format!("{head}0.5,,1.0\n")) {
        TableError::Fields { row, fields, expected } => assert_eq!((row, fields, expected), (1, 3, 4)),
        e => panic!("{e:?}"),
    }
    match csv_error(&format!("{head}0.5,,1.0,0.0,7\n")) {
        TableError::Fields { row, fields, expected } => assert_eq!((row, fields, expected), (1, 5, 4)),
        e => panic!("{e:?}"),
    }
    // The reader's own numbers: an interpolated row, `-0.0` and a subnormal.
    let sol = Solution::read_csv(format!("{head}0.5,,-0.0,5e-324\n").as_bytes()).unwrap();
    assert_eq!((sol.step[1], sol.q[1][0].to_bits(), sol.p[1][0].to_bits()), (None, (-0.0f64).to_bits(), 1));
}

#[test]
fn read_json_refuses_values_that_are_not_numbers_or_the_documented_texts() {
    for bad in ["null", r#""nan""#, r#""Infinity""#, r#""1.5""#, r#""NaN:0x7ff0000000000000""#, "true"] {
        let text = json(&format!("[0.0,{bad},1.0]"), STEP, Q, P, P, ENERGY);
        assert!(matches!(Solution::read_json(text.as_bytes()), Err(TableError::Json(_))), "{bad}");
    }
    // A row of `q` with two values where the others have one (ragged rows).
    let text = json(T, STEP, "[[1.0],[0.875,0.0],[0.5]]", P, P, ENERGY);
    let e = Solution::read_json(text.as_bytes()).unwrap_err();
    assert!(matches!(e, TableError::Json(_)) && e.to_string().contains("1 values in row 1, as in row 0"), "{e}");
    // Rows of `p` wider than those of `q`.
    let text = json(T, STEP, Q, "[[0.0,1.0],[-0.5,1.0],[-0.75,1.0]]", P, ENERGY);
    match Solution::read_json(text.as_bytes()).unwrap_err() {
        TableError::Width { column, width, expected } => assert_eq!((column, width, expected), ("p", 2, 1)),
        e => panic!("{e:?}"),
    }
    // Integers are numbers.
    let sol = Solution::read_json(json("[0,1,2]", STEP, Q, P, P, ENERGY).as_bytes()).unwrap();
    assert_eq!(sol.t, [0.0, 1.0, 2.0]);
}

fn runner(cases: u32) -> proptest::test_runner::TestRunner {
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let config = Config { cases, failure_persistence: None, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]))
}

/// Any bit patterns, NaNs of every payload among them, in every column.
#[test]
fn any_bits_round_trip_in_both_formats() {
    use proptest::prelude::*;
    let rows = proptest::collection::vec((any::<[u64; 8]>(), any::<Option<u64>>()), 0..12);
    runner(500)
        .run(&rows, |rows| {
            let x = |i: usize| rows.iter().map(move |(b, _)| f64::from_bits(b[i]));
            let pair = |i: usize| x(i).zip(x(i + 1)).map(|(a, b)| [a, b]).collect::<Vec<_>>();
            let sol = table(
                x(0).collect(),
                rows.iter().map(|(_, s)| *s).collect(),
                pair(1),
                pair(3),
                pair(5),
                x(7).collect(),
            );
            let mut csv = Vec::new();
            sol.write_csv(&mut csv).unwrap();
            let back = Solution::read_csv(csv.as_slice()).unwrap();
            prop_assert_eq!(column_bits(&back), column_bits(&sol));
            prop_assert_eq!(&back.step, &sol.step);
            let mut json = Vec::new();
            sol.write_json(&mut json).unwrap();
            let back = Solution::read_json(json.as_slice()).unwrap();
            prop_assert_eq!(column_bits(&back), column_bits(&sol));
            prop_assert_eq!(&back.step, &sol.step);
            Ok(())
        })
        .unwrap();
}

/// Files with bytes replaced, inserted or cut off: the readers return a
/// typed error or a solution the writers accept, and never panic.
#[test]
fn damaged_files_are_errors_or_consistent_solutions() {
    use proptest::prelude::*;
    let mut csv = Vec::new();
    three_rows().write_csv(&mut csv).unwrap();
    let mut json = Vec::new();
    three_rows().write_json(&mut json).unwrap();
    let bytes = b",:[]{}\"\n0123456789.-eNaIfnul ";
    let edit = (any::<bool>(), 0..4usize, proptest::collection::vec((any::<usize>(), 0..bytes.len()), 1..4));
    let (csv_errors, json_errors) = (std::cell::Cell::new(0), std::cell::Cell::new(0));
    runner(3000)
        .run(&edit, |(use_csv, kind, places)| {
            let mut file = if use_csv { csv.clone() } else { json.clone() };
            for (at, b) in places {
                let at = at % file.len().max(1);
                match kind {
                    0 | 1 => {
                        if let Some(x) = file.get_mut(at) {
                            *x = bytes[b];
                        }
                    }
                    2 => file.insert(at, bytes[b]),
                    _ => file.truncate(at),
                }
            }
            let read = if use_csv { Solution::read_csv(file.as_slice()) } else { Solution::read_json(file.as_slice()) };
            match read {
                Ok(sol) => {
                    sol.write_csv(Vec::new()).unwrap();
                    sol.write_json(Vec::new()).unwrap();
                }
                Err(_) if use_csv => csv_errors.set(csv_errors.get() + 1),
                Err(_) => json_errors.set(json_errors.get() + 1),
            }
            Ok(())
        })
        .unwrap();
    let (csv_errors, json_errors) = (csv_errors.get(), json_errors.get());
    assert!(csv_errors > 100 && json_errors > 100, "{csv_errors} {json_errors}");
}
