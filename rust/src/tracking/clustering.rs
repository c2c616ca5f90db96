//! Clustering: the split of a scan's tracks into independent groups connected by shared gated
//! detections (union-find), so that JPDA runs per cluster.

use super::jpda::TrackHypotheses;

/// Groups track indices into clusters connected by shared detections (union-find). Tracks
/// without detections are singleton clusters. Clusters come out ordered by their first track.
pub fn clusters(tracks: &[TrackHypotheses], n_detections: usize) -> Vec<Vec<usize>> {
    group_by_shared_detections(tracks.len(), n_detections, |t| {
        tracks[t].detections.iter().map(|&(d, _)| d)
    })
}

/// Union-find of `n_tracks` tracks connected when they share a detection; `detections_of(t)`
/// lists the detection indices (< `n_detections`) of track `t`. Tracks without detections are
/// singleton groups; groups come out ordered by their first track, tracks ascending.
pub fn group_by_shared_detections<I: Iterator<Item = usize>>(
    n_tracks: usize,
    n_detections: usize,
    detections_of: impl Fn(usize) -> I,
) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n_tracks).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    let mut owner = vec![usize::MAX; n_detections];
    for t in 0..n_tracks {
        for d in detections_of(t) {
            if owner[d] == usize::MAX {
                owner[d] = t;
            } else {
                let (a, b) = (find(&mut parent, owner[d]), find(&mut parent, t));
                if a != b {
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
    }
    // Group number of each root, in order of first track.
    let mut index = vec![usize::MAX; n_tracks];
    let mut out: Vec<Vec<usize>> = Vec::new();
    for t in 0..n_tracks {
        let r = find(&mut parent, t);
        if index[r] == usize::MAX {
            index[r] = out.len();
            out.push(Vec::new());
        }
        out[index[r]].push(t);
    }
    out
}
