//! The numbers behind one newest state of [`super::StoneSoupKit`]: the track's history entry
//! and the predictor's prediction from the entry before it, read from the native core.

use super::*;

impl StoneSoupKit {
    /// The numbers of history entry `last` of a track (its state `dt` seconds after entry
    /// `last` − 1, of the scan before), or None when it falls back (see `newest`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn gather(
        &mut self,
        models: &Bound<'_, PyList>,
        tr: &crate::tracking::track::Track,
        last: usize,
        dt: f64,
        (fm, q): (&DMatrix<f64>, &DMatrix<f64>),
        (zs, zm): (&[f64], usize),
        mixture: bool,
        hypotheses: bool,
    ) -> PyResult<Option<Row>> {
        let h = &tr.history;
        let len = h.times.len();
        if last < 1
            || last >= len
            || h.scan[last - 1] != h.scan[last] - 1
            || h.times[last] - h.times[last - 1] != dt
            || h.assoc_offsets.len() != len + 1
        {
            return Ok(None);
        }
        let prev = last - 1;
        let update = h.is_update[last];
        let (a, b) = (h.assoc_offsets[last], h.assoc_offsets[last + 1]);
        let mut row = Row {
            last,
            update,
            pred: None,
            assoc: h.assoc_detection[a..b]
                .iter()
                .zip(&h.assoc_probability[a..b])
                .map(|(&d, &p)| (d as usize, p))
                .collect(),
            missed: h.missed_probability[last],
            det: h.detection[last],
            distance: f64::NAN,
            mps: Vec::new(),
            mp_of: Vec::new(),
        };
        if !update || !hypotheses {
            return Ok(Some(row));
        }
        if h.assoc_detection[a..b]
            .iter()
            .any(|&d| d < 0 || d as usize >= models.len())
            || h.detection[last] >= models.len() as i64
        {
            return Ok(None);
        }
        let n = fm.nrows();
        let x0 = DVector::from_row_slice(&h.states[prev * n..(prev + 1) * n]);
        let p0 = DMatrix::from_row_slice(n, n, &h.covariances[prev * n * n..(prev + 1) * n * n]);
        // Stone Soup's KalmanPredictor: F x, F P Fᵀ + Q, not symmetrised (unlike
        // `crate::kalman::predict`), as the Python builders compute it.
        let xp = fm * x0;
        let pp = fm * p0 * fm.transpose() + q;
        let jpda = mixture && row.missed.is_finite();
        let wanted: Vec<usize> = if jpda {
            row.assoc.iter().map(|&(d, _)| d).collect()
        } else if row.det >= 0 {
            if self.measure == 0 {
                return Ok(None);
            }
            vec![row.det as usize]
        } else {
            Vec::new()
        };
        for d in wanted {
            let model = models.get_item(d)?;
            let key = model.as_ptr() as usize;
            if let Some(i) = row.mps.iter().position(|m| m.model == key) {
                row.mp_of.push(i);
                continue;
            }
            let Some(hr) = self.linear(&model)? else {
                return Ok(None);
            };
            let (hm, r) = (&hr.0, &hr.1);
            if hm.nrows() != zm || hm.ncols() != n || r.nrows() != zm || r.ncols() != zm {
                return Ok(None);
            }
            let cross = &pp * hm.transpose();
            let (zp, s) = (hm * &xp, hm * &cross + r);
            row.mp_of.push(row.mps.len());
            row.mps.push(MeasurementPrediction {
                model: key,
                z: zp,
                s,
                c: cross,
            });
        }
        if !jpda && row.det >= 0 {
            // The hypothesiser's measure: (squared) Mahalanobis distance of the detection.
            let d = row.det as usize;
            let mp = &row.mps[0];
            let v = DVector::from_row_slice(&zs[d * zm..(d + 1) * zm]) - &mp.z;
            let Some(chol) = mp.s.clone().cholesky() else {
                return Ok(None);
            };
            let d2 = v.dot(&chol.solve(&v));
            row.distance = if self.measure == 1 { d2.sqrt() } else { d2 };
        }
        row.pred = Some((xp, pp));
        Ok(Some(row))
    }
}
