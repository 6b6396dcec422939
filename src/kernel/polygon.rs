//! Polygon geometry (interim: replaced by the full module with triangulation).
use glam::DVec3;

pub fn newell_normal(points: &[DVec3]) -> DVec3 {
    let n = points.len();
    let mut normal = DVec3::ZERO;
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        normal.x += (a.y - b.y) * (a.z + b.z);
        normal.y += (a.z - b.z) * (a.x + b.x);
        normal.z += (a.x - b.x) * (a.y + b.y);
    }
    normal
}

pub fn unit_normal(points: &[DVec3]) -> Option<DVec3> {
    let n = newell_normal(points);
    let len = n.length();
    (len > 1e-300 && len.is_finite()).then(|| n / len)
}

pub fn area(points: &[DVec3]) -> f64 {
    newell_normal(points).length() * 0.5
}
