use std::time::Instant;
use vatcal_core::{CellFile, ParamSet};
use vatcal_identification::*;
use vatcal_kinematics::Model;
use vatcal_sim::truth::*;
fn t<F: FnMut()>(name: &str, n: usize, mut f: F) {
    let s = Instant::now();
    for _ in 0..n { f(); }
    println!("{name:30} {:8.1} µs", s.elapsed().as_secs_f64() * 1e6 / n as f64);
}
fn main() {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml")).unwrap();
    let nominal = Model::from_cell(&cell).unwrap();
    let truth = perturbed_truth(&nominal, 2, &ErrorBudget::realistic());
    let starts = probe_start_poses(&nominal, 44, 102);
    let mut data = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.003 }, 202);
    data.truncate(40);
    let p = ParamSet::paper34();
    let fit = identify(&nominal, &data, &p, &IdentifyOptions::default()).unwrap();
    if std::env::var("PROFILE").is_ok() {
        t("profile loop", 2000, || { identify(&nominal, &data, &p, &IdentifyOptions::default()).unwrap(); });
        return;
    }
    println!("iterations {}", fit.iterations.len());
    let gn = identify(&nominal, &data, &p, &IdentifyOptions::with_method(Method::GaussNewton)).unwrap();
    println!("gn iterations {} {:?}", gn.iterations.len(), gn.termination);
    for lam in [1e-3, 1e-4, 1e-6, 1e-8] {
        for st in [1e-10, 1e-8] {
            let o = IdentifyOptions { initial_lambda: lam, step_tolerance: st, check_identifiability: false, ..Default::default() };
            let f = identify(&nominal, &data, &p, &o).unwrap();
            let name = format!("lm lam {lam:e} st {st:e} its {} {:?}", f.iterations.len(), f.termination);
            t(&name, 300, || { identify(&nominal, &data, &p, &o).unwrap(); });
        }
    }
    t("identify lm", 300, || { identify(&nominal, &data, &p, &IdentifyOptions::default()).unwrap(); });
    t("identify lm nocheck", 300, || { identify(&nominal, &data, &p, &IdentifyOptions { check_identifiability: false, ..Default::default() }).unwrap(); });
    t("check_identifiable", 300, || { vatcal_observability::check_identifiable(&nominal, &data, &p).unwrap(); });
    t("model clone", 3000, || { std::hint::black_box(nominal.clone()); });
    let mut m2 = fit.model.clone();
    let vals = fit.values.clone();
    t("set_params", 3000, || { m2.set_params(&p, &vals).unwrap(); });
    t("residuals x40 (compliant)", 3000, || { for d in &data { std::hint::black_box(fit.model.residual(d).unwrap()); } });
    t("residuals x40 (nominal)", 3000, || { for d in &data { std::hint::black_box(nominal.residual(d).unwrap()); } });
    let mut block = vec![0.0; 102];
    t("jacobian x40 (compliant)", 3000, || { for d in &data { std::hint::black_box(fit.model.measurement_jacobian_into(d, &p.0, &mut block).unwrap()); } });
    t("gravity torques x40", 3000, || { for d in &data { std::hint::black_box(fit.model.gravity_torques(&d.q)); } });
    let a = faer::Mat::<f64>::from_fn(120, 34, |i, j| ((i * 31 + j * 17) % 23) as f64 - 11.0 + if i == j { 50.0 } else { 0.0 });
    t("faer qr 120x34 (alloc)", 3000, || { std::hint::black_box(a.qr()); });
    let r = faer::Mat::<f64>::from_fn(34, 34, |i, j| if i <= j { 1.0 + ((i * 7 + j) % 5) as f64 } else { 0.0 });
    t("faer svd 34x34", 1000, || { std::hint::black_box(r.thin_svd().unwrap()); });
    t("faer sv 34x34", 1000, || { std::hint::black_box(r.singular_values().unwrap()); });
    let rn = nalgebra::DMatrix::<f64>::from_fn(34, 34, |i, j| r[(i, j)]);
    t("nalgebra svd 34x34", 1000, || { std::hint::black_box(rn.clone().svd(true, true)); });
    t("nalgebra sv 34x34", 1000, || { std::hint::black_box(rn.clone().singular_values()); });
    let rf = faer::Mat::<f64>::from_fn(34, 34, |i, j| ((i * 31 + j * 17) % 23) as f64 - 11.0 + if i == j { 50.0 } else { 0.0 });
    t("faer svd 34x34 general", 1000, || { std::hint::black_box(rf.thin_svd().unwrap()); });
    let an = nalgebra::DMatrix::<f64>::from_fn(120, 34, |i, j| a[(i, j)]);
    t("nalgebra qr 120x34", 1000, || { std::hint::black_box(an.clone().qr()); });
    t("nalgebra svd 120x34", 1000, || { std::hint::black_box(an.clone().svd(true, true)); });
    t("faer svd 120x34", 1000, || { std::hint::black_box(a.thin_svd().unwrap()); });
}
