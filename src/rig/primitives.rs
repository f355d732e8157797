//! Hand primitives (ellipsoid, capsule), their ray intersections and image-space culling boxes.

use crate::geometry::{LensModel, Pose};
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// An axis-aligned ellipsoid.
#[derive(Debug, Clone, Copy)]
pub struct Ellipsoid {
    pub(crate) centre: V3,
    pub(crate) radii: V3,
}

/// A capsule: all points within `radius` of the segment `a`–`b`.
#[derive(Debug, Clone, Copy)]
pub struct Capsule {
    a: V3,
    b: V3,
    radius: f64,
}

/// One primitive of the hand.
#[derive(Debug, Clone, Copy)]
pub enum Shape {
    Ellipsoid(Ellipsoid),
    Capsule(Capsule),
}

/// An axis-aligned box in image pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelBox {
    pub u_min: f64,
    pub u_max: f64,
    pub v_min: f64,
    pub v_max: f64,
}

/// A hand primitive with its culling boxes in the camera and projector images.
#[derive(Debug, Clone, Copy)]
pub struct HandPart {
    pub shape: Shape,
    pub camera_box: PixelBox,
    pub projector_box: PixelBox,
    /// Maps the part's points (hand frame) to where they sit on the hand at rest: the frame the
    /// skin's texture is printed in, so the texture moves with the skin.
    pub rest_from_hand: nalgebra::Isometry3<f64>,
}

impl PixelBox {
    pub const EVERYWHERE: PixelBox = PixelBox {
        u_min: f64::NEG_INFINITY,
        u_max: f64::INFINITY,
        v_min: f64::NEG_INFINITY,
        v_max: f64::INFINITY,
    };

    #[inline]
    pub fn contains(&self, (u, v): (f64, f64)) -> bool {
        u >= self.u_min && u <= self.u_max && v >= self.v_min && v <= self.v_max
    }

    /// A box that contains the image of the sphere (`centre`, `radius`, in the frame that
    /// `device_from_frame` maps into the device's frame). It projects the eight corners of the
    /// sphere's bounding cube and pads by 5 % and 3 px, which covers the bending of the moderate
    /// lens distortion between corners. A sphere reaching behind the lens gets no culling.
    pub fn around_sphere(
        lens: &LensModel,
        device_from_frame: &Pose,
        centre: V3,
        radius: f64,
    ) -> PixelBox {
        let mut b = PixelBox {
            u_min: f64::INFINITY,
            u_max: f64::NEG_INFINITY,
            v_min: f64::INFINITY,
            v_max: f64::NEG_INFINITY,
        };
        for corner in 0..8 {
            let offset = V3::new(
                if corner & 1 == 0 { -radius } else { radius },
                if corner & 2 == 0 { -radius } else { radius },
                if corner & 4 == 0 { -radius } else { radius },
            );
            let p = device_from_frame.transform(&(centre + offset));
            if p.z < 1.0 {
                return PixelBox::EVERYWHERE;
            }
            let Some((u, v)) = lens.project(&p) else {
                return PixelBox::EVERYWHERE;
            };
            b.u_min = b.u_min.min(u);
            b.u_max = b.u_max.max(u);
            b.v_min = b.v_min.min(v);
            b.v_max = b.v_max.max(v);
        }
        let pad_u = 0.05 * (b.u_max - b.u_min) + 3.0;
        let pad_v = 0.05 * (b.v_max - b.v_min) + 3.0;
        PixelBox {
            u_min: b.u_min - pad_u,
            u_max: b.u_max + pad_u,
            v_min: b.v_min - pad_v,
            v_max: b.v_max + pad_v,
        }
    }
}

impl Shape {
    /// Nearest hit `(t, outward normal)` along `origin + t·dir` with `t > 1e-6`.
    #[inline]
    pub fn intersect(&self, origin: &V3, dir: &V3) -> Option<(f64, V3)> {
        match self {
            Shape::Ellipsoid(e) => e.intersect(origin, dir),
            Shape::Capsule(c) => c.intersect(origin, dir),
        }
    }

    /// A sphere that contains the shape.
    pub fn bounding_sphere(&self) -> (V3, f64) {
        match self {
            Shape::Ellipsoid(e) => (e.centre, e.radii.max()),
            Shape::Capsule(c) => ((c.a + c.b) * 0.5, (c.b - c.a).norm() * 0.5 + c.radius),
        }
    }
}

impl Ellipsoid {
    pub fn new(centre: V3, radii: V3) -> Self {
        Self { centre, radii }
    }

    fn intersect(&self, origin: &V3, dir: &V3) -> Option<(f64, V3)> {
        let o = (origin - self.centre).component_div(&self.radii);
        let d = dir.component_div(&self.radii);
        let a = d.norm_squared();
        let b = o.dot(&d);
        let c = o.norm_squared() - 1.0;
        let h = b * b - a * c;
        if h < 0.0 {
            return None;
        }
        let t = (-b - h.sqrt()) / a;
        if t <= 1e-6 {
            return None;
        }
        let p = origin + dir * t - self.centre;
        let r2 = self.radii.component_mul(&self.radii);
        Some((t, p.component_div(&r2).normalize()))
    }
}

impl Capsule {
    pub fn new(a: V3, b: V3, radius: f64) -> Self {
        Self { a, b, radius }
    }

    fn intersect(&self, origin: &V3, dir: &V3) -> Option<(f64, V3)> {
        let ba = self.b - self.a;
        let oa = origin - self.a;
        let baba = ba.dot(&ba);
        let bard = ba.dot(dir);
        let baoa = ba.dot(&oa);
        let rdoa = dir.dot(&oa);
        let oaoa = oa.dot(&oa);
        let r2 = self.radius * self.radius;
        let a = baba - bard * bard;
        let b = baba * rdoa - baoa * bard;
        let c = baba * oaoa - baoa * baoa - r2 * baba;
        let h = b * b - a * c;
        if h < 0.0 {
            return None;
        }
        let mut t = f64::INFINITY;
        if a > 1e-12 {
            let tb = (-b - h.sqrt()) / a;
            let y = baoa + tb * bard;
            if y > 0.0 && y < baba && tb > 1e-6 {
                t = tb;
            }
        }
        if !t.is_finite() {
            // Hemispherical caps.
            for centre in [self.a, self.b] {
                let oc = origin - centre;
                let bb = oc.dot(dir);
                let cc = oc.norm_squared() - r2;
                let hh = bb * bb - cc;
                if hh > 0.0 {
                    let tc = -bb - hh.sqrt();
                    if tc > 1e-6 && tc < t {
                        t = tc;
                    }
                }
            }
        }
        if !t.is_finite() {
            return None;
        }
        let p = origin + dir * t;
        let s = ((p - self.a).dot(&ba) / baba).clamp(0.0, 1.0);
        let normal = (p - (self.a + ba * s)).normalize();
        Some((t, normal))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn capsule_hits_body_and_caps() {
        let cap = Capsule::new(V3::new(0.0, 0.0, 100.0), V3::new(50.0, 0.0, 100.0), 10.0);
        let (t, n) = cap.intersect(&V3::new(25.0, 0.0, 0.0), &V3::z()).unwrap();
        assert!((t - 90.0).abs() < 1e-9 && (n + V3::z()).norm() < 1e-9);
        let (t, _) = cap.intersect(&V3::new(-5.0, 0.0, 0.0), &V3::z()).unwrap();
        assert!((t - (100.0 - 75f64.sqrt())).abs() < 1e-9);
        assert!(cap.intersect(&V3::new(-11.0, 0.0, 0.0), &V3::z()).is_none());
    }
}
