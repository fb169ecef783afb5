//! Orbit camera in millimetres: yaw/pitch around a target point, distance along the view axis.

use glam::{DMat4, DVec3, Mat4};

/// Orbit/pan/zoom camera. At yaw = pitch = 0 it looks along −z, i.e. at the front of a face
/// that looks towards +z (the scan frame).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OrbitCamera {
    /// Point the camera orbits and looks at, mm.
    pub target_mm: DVec3,
    /// Distance from the eye to the target, mm.
    pub distance_mm: f64,
    /// Rotation about the vertical (y) axis, radians; positive turns towards the subject's left.
    pub yaw_rad: f64,
    /// Elevation, radians, clamped to ±89°.
    pub pitch_rad: f64,
    /// Vertical field of view, radians (default 30°).
    pub fov_y_rad: f64,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        OrbitCamera {
            target_mm: DVec3::ZERO,
            distance_mm: 400.0,
            yaw_rad: 0.0,
            pitch_rad: 0.0,
            fov_y_rad: 30f64.to_radians(),
        }
    }
}

impl OrbitCamera {
    /// Frames a bounding box from the front, so the whole box fits the view.
    pub fn framing(bbox_min_mm: DVec3, bbox_max_mm: DVec3) -> Self {
        let mut cam = OrbitCamera::default();
        cam.frame(bbox_min_mm, bbox_max_mm);
        cam
    }

    /// Re-targets on a bounding box and backs off until it fits; keeps the orientation.
    pub fn frame(&mut self, bbox_min_mm: DVec3, bbox_max_mm: DVec3) {
        self.target_mm = (bbox_min_mm + bbox_max_mm) * 0.5;
        let radius = ((bbox_max_mm - bbox_min_mm).length() * 0.5).max(1.0);
        self.distance_mm = radius / (self.fov_y_rad * 0.5).sin() * 1.05;
    }

    /// Unit vector from the target to the eye.
    pub fn back(&self) -> DVec3 {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        DVec3::new(sy * cp, sp, cy * cp)
    }

    pub fn eye_mm(&self) -> DVec3 {
        self.target_mm + self.back() * self.distance_mm
    }

    /// Camera right and up vectors in world space.
    pub fn right_up(&self) -> (DVec3, DVec3) {
        let back = self.back();
        let right = DVec3::Y.cross(back).normalize_or(DVec3::X);
        (right, back.cross(right))
    }

    pub fn view(&self) -> DMat4 {
        let (_, up) = self.right_up();
        glam::dcamera::rh::view::look_at_mat4(self.eye_mm(), self.target_mm, up)
    }

    /// Projection with depth in [0, 1] (wgpu's convention).
    pub fn projection(&self, aspect: f64) -> DMat4 {
        let near = (self.distance_mm * 0.02).max(0.01);
        let far = self.distance_mm * 20.0 + 1000.0;
        glam::dcamera::rh::proj::directx::perspective(self.fov_y_rad, aspect.max(1e-3), near, far)
    }

    /// The matrix the shaders use (computed in f64, then rounded once).
    pub fn view_proj(&self, aspect: f64) -> Mat4 {
        (self.projection(aspect) * self.view()).as_mat4()
    }

    /// Maps a world point to viewport pixels (origin top-left); `None` behind the camera.
    pub fn project_to_pixels(
        &self,
        p_mm: DVec3,
        width_px: f64,
        height_px: f64,
    ) -> Option<[f64; 2]> {
        let clip = (self.projection(width_px / height_px) * self.view()) * p_mm.extend(1.0);
        if clip.w <= 1e-9 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some([
            (ndc.x * 0.5 + 0.5) * width_px,
            (0.5 - ndc.y * 0.5) * height_px,
        ])
    }

    /// Ray through a viewport pixel: (origin, unit direction), for picking.
    pub fn ray_through_pixel(
        &self,
        x_px: f64,
        y_px: f64,
        width_px: f64,
        height_px: f64,
    ) -> (DVec3, DVec3) {
        let ndc_x = x_px / width_px * 2.0 - 1.0;
        let ndc_y = 1.0 - y_px / height_px * 2.0;
        let tan = (self.fov_y_rad * 0.5).tan();
        let aspect = width_px / height_px;
        let (right, up) = self.right_up();
        let dir = -self.back() + right * (ndc_x * tan * aspect) + up * (ndc_y * tan);
        (self.eye_mm(), dir.normalize())
    }

    /// Drag to orbit: `dx`, `dy` in pixels.
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        self.yaw_rad -= dx * 0.008;
        self.pitch_rad =
            (self.pitch_rad + dy * 0.008).clamp(-89f64.to_radians(), 89f64.to_radians());
    }

    /// Drag to pan: moves the target in the view plane so the surface follows the pointer.
    pub fn pan(&mut self, dx: f64, dy: f64, viewport_height_px: f64) {
        let mm_per_px =
            2.0 * self.distance_mm * (self.fov_y_rad * 0.5).tan() / viewport_height_px.max(1.0);
        let (right, up) = self.right_up();
        self.target_mm += (-right * dx + up * dy) * mm_per_px;
    }

    /// Scroll to zoom: factor > 1 moves closer.
    pub fn zoom(&mut self, factor: f64) {
        self.distance_mm = (self.distance_mm / factor.max(1e-3)).clamp(1.0, 1e6);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_view_looks_down_minus_z_and_projects_target_to_centre() {
        let cam = OrbitCamera::framing(
            DVec3::new(-70.0, -100.0, -1300.0),
            DVec3::new(70.0, 100.0, -1200.0),
        );
        assert!((cam.back() - DVec3::Z).length() < 1e-12);
        let c = cam.project_to_pixels(cam.target_mm, 800.0, 600.0).unwrap();
        assert!((c[0] - 400.0).abs() < 1e-6 && (c[1] - 300.0).abs() < 1e-6);
        // +x (subject's left) appears on the right of a front view, +y at the top.
        let r = cam
            .project_to_pixels(cam.target_mm + DVec3::new(10.0, 10.0, 0.0), 800.0, 600.0)
            .unwrap();
        assert!(r[0] > 400.0 && r[1] < 300.0);
    }

    #[test]
    fn pixel_ray_hits_the_projected_point() {
        let mut cam = OrbitCamera::default();
        cam.orbit(40.0, -25.0);
        let p = DVec3::new(12.0, -7.0, 30.0);
        let px = cam.project_to_pixels(p, 640.0, 480.0).unwrap();
        let (o, d) = cam.ray_through_pixel(px[0], px[1], 640.0, 480.0);
        let along = (p - o).dot(d);
        assert!((o + d * along - p).length() < 1e-6);
    }

    #[test]
    fn whole_box_is_inside_the_view_after_framing() {
        let (lo, hi) = (
            DVec3::new(-70.0, -110.0, -1290.0),
            DVec3::new(75.0, 120.0, -1190.0),
        );
        let cam = OrbitCamera::framing(lo, hi);
        for i in 0..8 {
            let corner = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let px = cam.project_to_pixels(corner, 1000.0, 1000.0).unwrap();
            assert!((0.0..=1000.0).contains(&px[0]) && (0.0..=1000.0).contains(&px[1]));
        }
    }
}
