//! curvo on the peers' NURBS workload: degree 3 × 3, 10 × 10 control points
//! P_ij = (i, j, 2 sin 0.7i cos 0.5j), weights 1 + 0.5 ((i + j) mod 3),
//! clamped uniform knots.
//!
//!   curvo-bench sample N      regular_sample_points, N × N points
//!   curvo-bench tessellate N  regular_tessellate, N × N points
//!   curvo-bench adaptive TOL  adaptive tessellate, norm tolerance TOL
//!
//! Each prints one JSON line: seconds (the operation only), vertices, faces,
//! sum_z (sum of z over the points) and point (S(0.3, 0.6)).

use std::time::Instant;

use curvo::prelude::*;
use nalgebra::{Point3, Point4};

const DEGREE: usize = 3;
const SIZE: usize = 10;

fn surface() -> NurbsSurface3D<f64> {
    let net = (0..SIZE)
        .map(|i| {
            (0..SIZE)
                .map(|j| {
                    let (x, y) = (i as f64, j as f64);
                    let z = 2.0 * (0.7 * x).sin() * (0.5 * y).cos();
                    let w = 1.0 + 0.5 * ((i + j) % 3) as f64;
                    Point4::new(x * w, y * w, z * w, w)
                })
                .collect()
        })
        .collect();
    NurbsSurface::new(DEGREE, DEGREE, knots(), knots(), net)
}

/// Clamped uniform: 0 and 1 repeated degree + 1 times, evenly spaced between.
fn knots() -> Vec<f64> {
    let spans = SIZE - DEGREE;
    let mut k = vec![0.0; DEGREE];
    k.extend((0..=spans).map(|s| s as f64 / spans as f64));
    k.extend(vec![1.0; DEGREE]);
    k
}

fn report(seconds: f64, points: &[Point3<f64>], faces: Option<usize>, s: &NurbsSurface3D<f64>) {
    let sum_z: f64 = points.iter().map(|p| p.z).sum();
    let p = s.point_at(0.3, 0.6);
    let faces = faces.map_or("null".to_string(), |f| f.to_string());
    println!(
        "{{\"seconds\": {seconds:.9}, \"vertices\": {}, \"faces\": {faces}, \"pairs\": null, \
         \"sum_z\": {sum_z:.6}, \"point\": [{:.7}, {:.7}, {:.7}]}}",
        points.len(),
        p.x,
        p.y,
        p.z
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (mode, value) = match args.as_slice() {
        [_, mode, value] => (mode.as_str(), value.as_str()),
        _ => panic!("usage: curvo-bench sample|tessellate N | adaptive TOL"),
    };
    let s = surface();
    match mode {
        "sample" => {
            let divs: usize = value.parse::<usize>().expect("N") - 1;
            let t = Instant::now();
            let rows = s.regular_sample_points(divs, divs);
            let seconds = t.elapsed().as_secs_f64();
            let points: Vec<_> = rows.into_iter().flatten().collect();
            report(seconds, &points, None, &s);
        }
        "tessellate" => {
            let divs: usize = value.parse::<usize>().expect("N") - 1;
            let t = Instant::now();
            let mesh = s.regular_tessellate(divs, divs);
            let seconds = t.elapsed().as_secs_f64();
            report(seconds, mesh.points(), Some(mesh.faces().len()), &s);
        }
        "adaptive" => {
            let tol: f64 = value.parse().expect("TOL");
            let options: AdaptiveTessellationOptions<f64> =
                AdaptiveTessellationOptions::default().with_norm_tolerance(tol);
            let t = Instant::now();
            let mesh = s.tessellate(Some(options));
            let seconds = t.elapsed().as_secs_f64();
            report(seconds, mesh.points(), Some(mesh.faces().len()), &s);
        }
        _ => panic!("unknown mode {mode}"),
    }
}
