//! Bindings of the Haar cascade trainer (`crate::cascade`): conversions only.

use super::{slice, to_py_err};
use crate::cascade::integral::IntegralImage;
use crate::cascade::train::{add_stage, train_cascade, StageReport, TrainParams, Windows};
use crate::cascade::{xml, Cascade};
use crate::error::Error;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn windows<'a>(name: &str, a: &'a PyReadonlyArray3<'_, u8>) -> PyResult<Windows<'a>> {
    let s = a.shape();
    Ok(Windows {
        pixels: slice(name, a)?,
        width: s[2],
        height: s[1],
    })
}

fn report_dict<'py>(py: Python<'py>, r: &StageReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("weak", r.weak)?;
    d.set_item("hit_rate", r.fit.hit_rate)?;
    d.set_item("false_alarm", r.fit.false_alarm)?;
    d.set_item("positives", r.positives)?;
    d.set_item("negatives", r.negatives)?;
    d.set_item("acceptance_before", r.acceptance_before)?;
    Ok(d)
}

/// A boosted cascade of Haar-like features; train with `HaarCascade.train`.
#[pyclass(module = "usvfast._core")]
pub struct HaarCascade {
    inner: Cascade,
    params: TrainParams,
    reports: Vec<StageReport>,
}

#[pymethods]
impl HaarCascade {
    /// Trains a cascade on `positives` `(p, h, w)` uint8 windows against negatives
    /// bootstrapped from `negative_pool` `(n, h, w)` uint8 (read in order).
    #[staticmethod]
    #[pyo3(signature = (
        positives, negative_pool, *, min_hit_rate=0.995, max_false_alarm=0.5, max_weak=50,
        max_stages=12, negatives_per_stage=1000, feature_step=4, target_false_alarm=1e-4
    ))]
    #[allow(clippy::too_many_arguments)]
    fn train(
        py: Python<'_>,
        positives: PyReadonlyArray3<'_, u8>,
        negative_pool: PyReadonlyArray3<'_, u8>,
        min_hit_rate: f64,
        max_false_alarm: f64,
        max_weak: usize,
        max_stages: usize,
        negatives_per_stage: usize,
        feature_step: usize,
        target_false_alarm: f64,
    ) -> PyResult<Self> {
        let params = TrainParams {
            min_hit_rate,
            max_false_alarm,
            max_weak,
            max_stages,
            negatives_per_stage,
            feature_step,
            target_false_alarm,
        };
        let p = windows("positives", &positives)?;
        let n = windows("negative_pool", &negative_pool)?;
        let (inner, reports) = py
            .detach(|| train_cascade(&p, &n, &params))
            .map_err(to_py_err)?;
        Ok(Self {
            inner,
            params,
            reports,
        })
    }

    /// Trains one more stage on all `positives` and `negatives` (e.g. wake false
    /// positives) with the training targets; returns its report.
    #[pyo3(signature = (positives, negatives, *, max_false_alarm=None, max_weak=None))]
    fn add_stage<'py>(
        &mut self,
        py: Python<'py>,
        positives: PyReadonlyArray3<'py, u8>,
        negatives: PyReadonlyArray3<'py, u8>,
        max_false_alarm: Option<f64>,
        max_weak: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut params = self.params;
        params.max_false_alarm = max_false_alarm.unwrap_or(params.max_false_alarm);
        params.max_weak = max_weak.unwrap_or(params.max_weak);
        let p = windows("positives", &positives)?;
        let n = windows("negatives", &negatives)?;
        let inner = &mut self.inner;
        let r = py
            .detach(|| add_stage(inner, &p, &n, &params))
            .map_err(to_py_err)?;
        self.reports.push(r);
        report_dict(py, &r)
    }

    /// One dict per stage: weak, hit_rate, false_alarm, positives, negatives,
    /// acceptance_before.
    #[getter]
    fn stage_reports<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.reports.iter().map(|r| report_dict(py, r)).collect()
    }

    /// Number of stages.
    #[getter]
    fn num_stages(&self) -> usize {
        self.inner.stages.len()
    }

    /// Window size `(width, height)` in pixels.
    #[getter]
    fn window_size(&self) -> (usize, usize) {
        (self.inner.width, self.inner.height)
    }

    /// Whether each window `(n, h, w)` uint8 of the cascade's size passes every stage.
    fn accepts<'py>(
        &self,
        py: Python<'py>,
        windows: PyReadonlyArray3<'py, u8>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let s = windows.shape();
        if (s[2], s[1]) != (self.inner.width, self.inner.height) {
            return Err(to_py_err(Error::dim(
                "windows",
                format!("(n, {}, {})", self.inner.height, self.inner.width),
                format!("{s:?}"),
            )));
        }
        let px = slice("windows", &windows)?;
        let size = s[1] * s[2];
        let out: Vec<bool> = (0..s[0])
            .map(|i| {
                IntegralImage::new(&px[i * size..(i + 1) * size], s[2], s[1])
                    .map(|ii| self.inner.accepts(&ii, 0, 0))
                    .unwrap_or(false)
            })
            .collect();
        Ok(PyArray1::from_vec(py, out).into_any())
    }

    /// Top-left corners `(k, 2)` (x, y px) of the accepted windows of a grey uint8 image
    /// `(H, W)` at this scale, on a grid of `step` pixels.
    #[pyo3(signature = (image, step=2))]
    fn scan<'py>(
        &self,
        py: Python<'py>,
        image: PyReadonlyArray2<'py, u8>,
        step: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let s = image.shape();
        let ii = IntegralImage::new(slice("image", &image)?, s[1], s[0]).map_err(to_py_err)?;
        let hits = py.detach(|| self.inner.scan(&ii, step));
        let flat: Vec<i64> = hits
            .iter()
            .flat_map(|&(x, y)| [x as i64, y as i64])
            .collect();
        Ok(PyArray1::from_vec(py, flat)
            .reshape([hits.len(), 2])?
            .into_any())
    }

    /// Reads a cascade from OpenCV cascade XML text (BOOST stumps on HAAR features, as
    /// `to_opencv_xml` writes it); ValueError naming what is malformed.
    #[staticmethod]
    fn from_opencv_xml(text: &str) -> PyResult<Self> {
        let inner = xml::from_opencv_xml(text).map_err(to_py_err)?;
        Ok(Self {
            inner,
            params: TrainParams {
                min_hit_rate: 0.995,
                max_false_alarm: 0.5,
                max_weak: 50,
                max_stages: 12,
                negatives_per_stage: 1000,
                feature_step: 4,
                target_false_alarm: 1e-4,
            },
            reports: Vec::new(),
        })
    }

    /// The cascade as OpenCV cascade XML (for `cv2.CascadeClassifier`).
    fn to_opencv_xml(&self) -> String {
        xml::to_opencv_xml(
            &self.inner,
            self.params.min_hit_rate,
            self.params.max_false_alarm,
            self.params.max_weak,
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<HaarCascade>()?;
    Ok(())
}
