//! OpenCV's cascade classifier XML (the format `opencv_traincascade` writes and
//! `cv2.CascadeClassifier` reads): BOOST stages of stumps on HAAR features.

use super::Cascade;
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
             <stageThreshold>{:.12e}</stageThreshold>\n      <weakClassifiers>",
            st.weak.len(),
            st.threshold
        );
        for w in &st.weak {
            let _ = writeln!(
                s,
                "        <_>\n          <internalNodes>\n            0 -1 {} {:.12e}</internalNodes>\n          \
                 <leafValues>\n            {:.12e} {:.12e}</leafValues></_>",
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

#[cfg(test)]
mod tests {
    use super::super::haar::{HaarFeature, WeightedRect};
    use super::super::{Cascade, Stage, Stump};
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
    }
}
