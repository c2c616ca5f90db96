//! Replays small Stone Soup JPDA / GNN reference runs (exported by
//! `tests/fixtures/export_stonesoup_runs.py` into `rust/tests/fixtures/stonesoup_runs.json`)
//! through the core tracker alone: same births and deaths at the same scans, same state times
//! and update/prediction kinds, means and covariances within 1e-9.

use nalgebra::{DMatrix, DVector};
use serde::Deserialize;
use usvfast_core::models::MotionModel;
use usvfast_core::tracking::jpda::Method;
use usvfast_core::tracking::track::Deleter;
use usvfast_core::tracking::tracker::{
    Association, Confirmation, GnnParams, JpdaParams, Measure, Sensor, Tracker, TrackerConfig,
};

#[derive(Deserialize)]
struct Fixture {
    runs: Vec<Run>,
}

#[derive(Deserialize)]
struct Scan {
    t: f64,
    z: Vec<[f64; 2]>,
    sensor: Vec<usize>,
}

#[derive(Deserialize)]
struct Record {
    born: usize,
    died: Option<usize>,
    times: Vec<f64>,
    means: Vec<Vec<f64>>,
    covars: Vec<Vec<Vec<f64>>>,
    is_update: Vec<bool>,
}

#[derive(Deserialize)]
struct Run {
    name: String,
    associator: String,
    q: f64,
    sensor_noise: Vec<Vec<Vec<f64>>>,
    prob_detect: f64,
    prob_gate: f64,
    clutter_density: f64,
    gnn_missed_distance: f64,
    delete_steps: usize,
    covar_trace: f64,
    init_steps: usize,
    missed_distance: f64,
    prior_velocity_var: f64,
    min_points: usize,
    scans: Vec<Scan>,
    tracks: Vec<Record>,
}

/// Code 5.7 ([`TrackerConfig::code_5_7`]) with the run's own values.
fn config(run: &Run) -> TrackerConfig {
    let h = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let mut c = TrackerConfig::code_5_7();
    c.motion_model = MotionModel::constant_velocity_2d(run.q).unwrap();
    c.sensors = run
        .sensor_noise
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let r = DMatrix::from_fn(2, 2, |a, b| r[a][b]);
            Sensor::new(h.clone(), r, None, None, 4, &format!("sensors[{i}]")).unwrap()
        })
        .collect();
    c.association = match run.associator.as_str() {
        "jpda" => Association::Jpda(JpdaParams {
            prob_detect: run.prob_detect,
            prob_gate: run.prob_gate,
            clutter_density: Some(run.clutter_density),
            include_all: false,
            method: Method::Ehm,
            max_hypotheses: None,
        }),
        _ => Association::Gnn(GnnParams {
            measure: Measure::Mahalanobis,
            missed_distance: run.gnn_missed_distance,
            include_all: false,
        }),
    };
    c.deleter = Deleter::Composite {
        deleters: vec![
            Deleter::StepsSinceUpdate(run.delete_steps),
            Deleter::CovarianceTrace {
                threshold: run.covar_trace,
                mapping: None,
            },
        ],
        intersect: false,
    };
    let pv = run.prior_velocity_var;
    let init = &mut c.initiator;
    init.prior_covariance = DMatrix::from_diagonal(&DVector::from_vec(vec![0.0, pv, 0.0, pv]));
    init.confirmation = Confirmation::MinPoints {
        min_points: run.min_points,
        updates_only: true,
    };
    init.deleter = Deleter::StepsSinceUpdate(run.init_steps);
    init.gnn.missed_distance = run.missed_distance;
    c
}

/// Our tracks of a run as `(born, died, track)`, ordered like the fixture's records.
fn replay(run: &Run) -> Vec<(usize, Option<usize>, usvfast_core::tracking::track::Track)> {
    let mut tr = Tracker::new(config(run)).unwrap();
    let mut born = std::collections::BTreeMap::new();
    let mut died = std::collections::BTreeMap::new();
    let mut alive: Vec<u64> = Vec::new();
    for (k, s) in run.scans.iter().enumerate() {
        let z: Vec<f64> = s.z.iter().flatten().copied().collect();
        tr.step(s.t, &z, &s.sensor).unwrap();
        let now: Vec<u64> = tr.tracks.iter().map(|t| t.id).collect();
        for id in &now {
            born.entry(*id).or_insert(k);
        }
        for id in alive.iter().filter(|i| !now.contains(i)) {
            died.insert(*id, k);
        }
        alive = now;
    }
    let mut out: Vec<_> = tr
        .tracks
        .iter()
        .chain(&tr.deleted)
        .map(|t| (born[&t.id], died.get(&t.id).copied(), t.clone()))
        .collect();
    let key = |t: &usvfast_core::tracking::track::Track| {
        let h = &t.history;
        (h.times[0], h.states[0], h.states[2])
    };
    out.sort_by(|a, b| {
        a.0.cmp(&b.0)
            .then(key(&a.2).partial_cmp(&key(&b.2)).unwrap())
    });
    out
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1.0)
}

#[test]
fn core_tracker_replays_stonesoup_runs() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/rust/tests/fixtures/stonesoup_runs.json"
    );
    let fx: Fixture = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert!(fx.runs.len() >= 4);
    let mut n_deaths = 0;
    for run in &fx.runs {
        let ours = replay(run);
        assert_eq!(
            ours.len(),
            run.tracks.len(),
            "{}: number of tracks",
            run.name
        );
        assert!(
            !run.tracks.is_empty(),
            "{}: no track proves nothing",
            run.name
        );
        for (i, ((born, died, t), r)) in ours.iter().zip(&run.tracks).enumerate() {
            let what = format!("{} track {i}", run.name);
            assert_eq!(
                (*born, *died),
                (r.born, r.died),
                "{what}: birth/death scans"
            );
            n_deaths += usize::from(r.died.is_some());
            let h = &t.history;
            assert_eq!(h.len(), r.times.len(), "{what}: number of states");
            assert_eq!(h.is_update, r.is_update, "{what}: update/prediction kinds");
            for k in 0..h.len() {
                assert!(close(h.times[k], r.times[k]), "{what}: time {k}");
                for j in 0..4 {
                    assert!(
                        close(h.states[4 * k + j], r.means[k][j]),
                        "{what}: mean {k}"
                    );
                    for l in 0..4 {
                        let v = h.covariances[16 * k + 4 * j + l];
                        assert!(close(v, r.covars[k][j][l]), "{what}: covariance {k}");
                    }
                }
            }
        }
    }
    assert!(n_deaths >= 1, "the runs exercise no deletion");
}
