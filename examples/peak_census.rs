//! Study (session 54, docs/evaluation.md section 1ao): how many of a scene's pixels see a
//! material's specular peak at each theta_d, and how their values compare with the truth at the
//! directions the mesh gives them. The losses of docs/materials.md lie at theta_d 60-75
//! degrees near the peak; this counts what the images hold there.
//!
//! `cargo run --release --example peak_census -- JOB.toml MATERIAL`
//!
//! - JOB.toml: a scene's job file (`bench materials ... --scratch DIR`, `bench accuracy ...
//!   --scratch DIR` or the independent renderer's scenes of docs/independent-scenes.md);
//! - MATERIAL: a neural MERL fit's name, the truth the values are compared with; when the job's
//!   folder holds `truth_labels.json` (objects of several materials), only the pixels of the
//!   faces of that material count.
//!
//! With the job's normals and with the normals refined as `reconstruct` refines them by default
//! (`eval::refine_case`, the object's materials found first, each with its own reflectance
//! table, as `reconstruct` does whatever `--materials` says), for the observed pixels and for
//! those the curvature filter keeps (assumption 1, as the pipeline applies it), per band of
//! theta_d: the pixels within 2, 6 and 12 degrees of the peak (theta_h, from the normals), and
//! their summed `r cos theta_i` over the truth's at the same directions (green channel): 1 where
//! the values are the truth's at the angles the normals give, below 1 where the normals' error
//! moves the peak's pixels off it.
//!
//! Neural MERL fits as truth are approximations of MERL, not measured MERL data.

use brdf_rig::brdf::BinValues;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::eval::{Perturb, find_material, load_case, refine_case};
use brdf_rig::reconstruct::Job;
use brdf_rig::reconstruct::core::CoreSettings;
use brdf_rig::reconstruct::observe::{Observation, ObserveSettings};
use brdf_rig::reconstruct::refine::RefineSettings;
use brdf_rig::reconstruct::reliable::select_reliable;
use brdf_rig::reconstruct::segment::SegmentSettings;
use brdf_rig::sim::truth_labels::read_truth_labels;
use std::path::PathBuf;

const THETA_D_BANDS: [f64; 6] = [0.0, 30.0, 45.0, 60.0, 75.0, 90.0];
const THETA_H_LIMITS: [f64; 3] = [2.0, 6.0, 12.0];

/// Pixels within `th_max` of the peak with theta_d in `[lo, hi)`, and their energy over the
/// truth's at the same directions.
fn band(obs: &[Observation], truth: &dyn BinValues, th_max: f64, lo: f64, hi: f64) -> (usize, f64) {
    let sel: Vec<&Observation> = obs
        .iter()
        .filter(|o| {
            let th = o.angles.theta_h.to_degrees();
            let td = o.angles.theta_d.to_degrees();
            th < th_max && td >= lo && td < hi
        })
        .collect();
    let bins: Vec<usize> = sel.iter().map(|o| o.bin).collect();
    let want: f64 = truth
        .values_at(&bins)
        .iter()
        .zip(&sel)
        .map(|(v, o)| v[1] * o.cos_theta_i)
        .sum();
    let got: f64 = sel.iter().map(|o| o.reflectance[1] * o.cos_theta_i).sum();
    (sel.len(), if want > 0.0 { got / want } else { f64::NAN })
}

fn census(label: &str, obs: &[Observation], truth: &dyn BinValues) {
    println!("{label}: {} pixels", obs.len());
    let mut head = String::from("  theta_h below |");
    for w in THETA_D_BANDS.windows(2) {
        head += &format!(" theta_d {:>2}-{:>2}: pixels, energy |", w[0], w[1]);
    }
    println!("{head}");
    for th in THETA_H_LIMITS {
        let mut line = format!("  {th:>4} deg      |");
        for w in THETA_D_BANDS.windows(2) {
            let (n, ratio) = band(obs, truth, th, w[0], w[1]);
            line += &format!(" {n:>17}, {ratio:>6.2} |");
        }
        println!("{line}");
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(args.len() >= 2, "usage: peak_census JOB.toml MATERIAL");
    let job_file = PathBuf::from(&args[0]);
    let job = Job::from_file(&job_file)?;
    let materials = load_dir(&default_dir())?;
    let truth = find_material(&materials, &args[1])?;
    let labels_file = job_file
        .parent()
        .map(|d| d.join("truth_labels.json"))
        .filter(|p| p.exists());
    let label = match &labels_file {
        Some(path) => {
            let truth_labels = read_truth_labels(path)?;
            let Some(label) = truth_labels.names.iter().position(|n| n == &args[1]) else {
                anyhow::bail!(
                    "{}: no material named {:?} (names: {:?})",
                    path.display(),
                    args[1],
                    truth_labels.names
                );
            };
            println!(
                "{}: the pixels of {} (label {label})",
                path.display(),
                args[1]
            );
            Some((truth_labels, label as u32))
        }
        None => None,
    };
    let observe = ObserveSettings::default();
    let scene = load_case(&job, &observe, &Perturb::default())?;
    let mesh = scene.mesh.clone();
    // The refinement finds the object's materials first, whatever `--materials` says.
    let segment = Some(SegmentSettings::default());
    let case = refine_case(scene, &observe, &RefineSettings::default(), segment, &mesh);
    let keep = |obs: Vec<Observation>| -> Vec<Observation> {
        match &label {
            Some((t, l)) => obs
                .into_iter()
                .filter(|o| t.labels.labels.get(o.face as usize) == Some(l))
                .collect(),
            None => obs,
        }
    };
    let reliable = CoreSettings::default().reliable;
    for (name, obs) in [
        ("the job's normals", keep(case.unrefined)),
        ("the normals refined", keep(case.observations)),
    ] {
        census(&format!("{name}, observed"), &obs, truth);
        let kept = select_reliable(&obs, &reliable);
        census(
            &format!("{name}, kept by the curvature filter"),
            &kept.pixels,
            truth,
        );
    }
    Ok(())
}
