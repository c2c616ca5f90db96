//! OpenCV's cascade classifier XML (the format `opencv_traincascade` writes and
//! `cv2.CascadeClassifier` reads): BOOST stages of stumps on HAAR features.

use super::haar::{HaarFeature, WeightedRect};
use super::{Cascade, Stage, Stump};
use crate::error::{Error, Result};
use std::fmt::Write;

/// The cascade as OpenCV cascade XML. `min_hit_rate`, `max_false_alarm` and `max_weak` are
/// recorded in `stageParams` (informative; OpenCV does not use them to detect).
pub fn to_opencv_xml(
    c: &Cascade,
    min_hit_rate: f64,
    max_false_alarm: f64,
    max_weak: usize,
) -> String {
    let mut s = String::new();
    let max_w = c
        .stages
        .iter()
        .map(|st| st.weak.len())
        .max()
        .unwrap_or(0)
        .max(max_weak);
    s.push_str("<?xml version=\"1.0\"?>\n<opencv_storage>\n<cascade>\n");
    s.push_str("  <stageType>BOOST</stageType>\n  <featureType>HAAR</featureType>\n");
    let _ = writeln!(
        s,
        "  <height>{}</height>\n  <width>{}</width>",
        c.height, c.width
    );
    let _ = writeln!(
        s,
        "  <stageParams>\n    <boostType>GAB</boostType>\n    <minHitRate>{min_hit_rate:e}</minHitRate>\n    \
         <maxFalseAlarm>{max_false_alarm:e}</maxFalseAlarm>\n    <weightTrimRate>1.</weightTrimRate>\n    \
         <maxDepth>1</maxDepth>\n    <maxWeakCount>{max_w}</maxWeakCount></stageParams>"
    );
    s.push_str(
        "  <featureParams>\n    <maxCatCount>0</maxCatCount>\n    <featSize>1</featSize>\n    \
         <mode>CORE</mode></featureParams>\n",
    );
    let _ = writeln!(s, "  <stageNum>{}</stageNum>\n  <stages>", c.stages.len());
    for (k, st) in c.stages.iter().enumerate() {
        let _ = writeln!(
            s,
            "    <!-- stage {k} -->\n    <_>\n      <maxWeakCount>{}</maxWeakCount>\n      \
             <stageThreshold>{:e}</stageThreshold>\n      <weakClassifiers>",
            st.weak.len(),
            st.threshold
        );
        for w in &st.weak {
            let _ = writeln!(
                s,
                "        <_>\n          <internalNodes>\n            0 -1 {} {:e}</internalNodes>\n          \
                 <leafValues>\n            {:e} {:e}</leafValues></_>",
                w.feature, w.threshold, w.left, w.right
            );
        }
        s.push_str("      </weakClassifiers></_>\n");
    }
    s.push_str("  </stages>\n  <features>\n");
    for f in &c.features {
        s.push_str("    <_>\n      <rects>\n");
        for r in &f.rects {
            let _ = writeln!(
                s,
                "        <_>\n          {} {} {} {} {:.1}</_>",
                r.x, r.y, r.w, r.h, r.weight
            );
        }
        s.push_str("      </rects>\n      <tilted>0</tilted></_>\n");
    }
    s.push_str("  </features>\n</cascade>\n</opencv_storage>\n");
    s
}

/// Contents between `<tag>` and `</tag>`, in order (no nesting of the same tag).
fn tag_values<'a>(s: &'a str, tag: &str) -> Vec<&'a str> {
    let (open, close) = (format!("<{tag}>"), format!("</{tag}>"));
    let mut out = Vec::new();
    let mut rest = s;
    while let Some(i) = rest.find(&open) {
        let after = &rest[i + open.len()..];
        let Some(j) = after.find(&close) else { break };
        out.push(&after[..j]);
        rest = &after[j + close.len()..];
    }
    out
}

fn numbers(s: &str, what: &str) -> Result<Vec<f64>> {
    s.split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| Error::param("xml", format!("{what}: not a number {t:?}")))
        })
        .collect()
}

fn one<'a>(s: &'a str, tag: &str) -> Result<&'a str> {
    tag_values(s, tag)
        .first()
        .copied()
        .ok_or_else(|| Error::param("xml", format!("no <{tag}>")))
}

/// Reads an OpenCV BOOST/HAAR cascade of stumps (as [`to_opencv_xml`] writes it). Fails with
/// an `InvalidParameter` error naming what is missing or malformed (trees deeper than stumps,
/// tilted features and more than three rectangles are refused).
pub fn from_opencv_xml(text: &str) -> Result<Cascade> {
    if one(text, "featureType")?.trim() != "HAAR" || one(text, "stageType")?.trim() != "BOOST" {
        return Err(Error::param(
            "xml",
            "only BOOST stages of HAAR features are supported",
        ));
    }
    let size = |tag: &str| -> Result<usize> {
        let v = one(text, tag)?.trim();
        v.parse::<usize>()
            .map_err(|_| Error::param("xml", format!("<{tag}> is not a size: {v:?}")))
    };
    let (width, height) = (size("width")?, size("height")?);
    if width < 3 || height < 3 {
        return Err(Error::param("xml", "window must be at least 3 x 3"));
    }
    let stages_s = one(text, "stages")?;
    let features_s = one(text, "features")?;
    let mut features = Vec::new();
    for rects in tag_values(features_s, "rects") {
        let mut rs = Vec::new();
        for item in tag_values(rects, "_") {
            let v = numbers(item, "rect")?;
            if v.len() != 5 || v[..4].iter().any(|&x| x < 0.0) {
                return Err(Error::param(
                    "xml",
                    format!("rect: expected x y w h weight, got {item:?}"),
                ));
            }
            let (x, y, w, h) = (v[0] as usize, v[1] as usize, v[2] as usize, v[3] as usize);
            if w == 0 || h == 0 || x + w > width || y + h > height {
                return Err(Error::param(
                    "xml",
                    format!("rect {item:?} leaves the window"),
                ));
            }
            rs.push(WeightedRect {
                x,
                y,
                w,
                h,
                weight: v[4],
            });
        }
        if rs.is_empty() || rs.len() > 3 {
            return Err(Error::param("xml", "a feature needs 1 to 3 rects"));
        }
        features.push(HaarFeature { rects: rs });
    }
    if features_s.contains("<tilted>1") {
        return Err(Error::param("xml", "tilted features are not supported"));
    }
    let counts = tag_values(stages_s, "maxWeakCount");
    let thresholds = tag_values(stages_s, "stageThreshold");
    let nodes = tag_values(stages_s, "internalNodes");
    let leaves = tag_values(stages_s, "leafValues");
    if counts.len() != thresholds.len() || nodes.len() != leaves.len() {
        return Err(Error::param("xml", "stages are incomplete"));
    }
    let mut stages = Vec::new();
    let mut k = 0;
    for (c, t) in counts.iter().zip(&thresholds) {
        let n = c
            .trim()
            .parse::<usize>()
            .map_err(|_| Error::param("xml", "bad maxWeakCount"))?;
        let threshold = numbers(t, "stageThreshold")?
            .first()
            .copied()
            .unwrap_or(0.0);
        let mut weak = Vec::new();
        for _ in 0..n {
            let (Some(nd), Some(lf)) = (nodes.get(k), leaves.get(k)) else {
                return Err(Error::param("xml", "fewer weak classifiers than announced"));
            };
            k += 1;
            let nd = numbers(nd, "internalNodes")?;
            let lf = numbers(lf, "leafValues")?;
            if nd.len() != 4 || lf.len() != 2 {
                return Err(Error::param("xml", "only stumps (depth 1) are supported"));
            }
            let feature = nd[2] as usize;
            if nd[2] < 0.0 || feature >= features.len() {
                return Err(Error::param(
                    "xml",
                    format!("feature index {} out of range", nd[2]),
                ));
            }
            weak.push(Stump {
                feature,
                threshold: nd[3],
                left: lf[0],
                right: lf[1],
            });
        }
        stages.push(Stage { weak, threshold });
    }
    Ok(Cascade {
        width,
        height,
        features,
        stages,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xml_lists_stages_and_features() {
        let mut c = Cascade::new(60, 30);
        c.features.push(HaarFeature {
            rects: vec![
                WeightedRect {
                    x: 0,
                    y: 0,
                    w: 12,
                    h: 6,
                    weight: -1.0,
                },
                WeightedRect {
                    x: 6,
                    y: 0,
                    w: 6,
                    h: 6,
                    weight: 2.0,
                },
            ],
        });
        c.stages.push(Stage {
            weak: vec![Stump {
                feature: 0,
                threshold: 0.25,
                left: -0.5,
                right: 0.75,
            }],
            threshold: -0.1,
        });
        let x = to_opencv_xml(&c, 0.995, 0.5, 10);
        assert!(x.contains("<stageNum>1</stageNum>"));
        assert!(x.contains("0 -1 0 2.5"));
        assert!(x.contains("6 0 6 6 2.0</_>"));
        assert!(x.contains("<width>60</width>"));
        assert_eq!(from_opencv_xml(&x).unwrap(), c);
        assert!(from_opencv_xml(&x.replace("6 0 6 6 2.0", "56 0 6 6 2.0")).is_err());
        assert!(from_opencv_xml("<cascade></cascade>").is_err());
    }
}
