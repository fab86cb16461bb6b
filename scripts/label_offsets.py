"""Where the found labels disagree with the truth, in rings of edges from the labels' boundary
(docs/materials.md, "Another material's colour near the boundary").

Usage:
  python3 scripts/label_offsets.py RUN SCENE

- RUN: the output folder of `brdf-rig reconstruct SCENE/job.toml --materials auto --out RUN`
  (its `material_map.ply`, binary little-endian as `reconstruct` writes it: per vertex x y z
  nx ny nz as floats, then label red green blue as bytes; faces as a byte count and ints);
- SCENE: a simulated scene of several materials (`bench materials --scratch DIR` keeps them),
  whose `truth_labels.json` gives each face's true material.

A vertex's true material is the one most of its faces have; a found label stands for the true
material most of its vertices have. Prints the count of vertices per (found label, truth), the
mislabelled vertices, and how many rings of edges each lies from the labels' boundary (0: a
vertex with a neighbour of another found label): mislabelled vertices at 0-1 rings are a
boundary drawn off the true one, not islands.
Pure Python.
"""
import collections, json, struct, sys


def read_map(path):
    b = open(path, "rb").read()
    end = b.index(b"end_header\n") + len(b"end_header\n")
    header = b[:end].decode()
    nv = int(header.split("element vertex ")[1].split()[0])
    nf = int(header.split("element face ")[1].split()[0])
    off, labels, faces = end, [], []
    for _ in range(nv):
        labels.append(struct.unpack_from("<6f4B", b, off)[6])
        off += 28
    for _ in range(nf):
        n = b[off]
        faces.append(struct.unpack_from("<%di" % n, b, off + 1))
        off += 1 + 4 * n
    return labels, faces


def rings(adj, labels):
    front = [v for v in range(len(labels)) if any(labels[u] != labels[v] for u in adj[v])]
    dist = {v: 0 for v in front}
    while front:
        nxt = []
        for v in front:
            for u in adj[v]:
                if u not in dist:
                    dist[u] = dist[v] + 1
                    nxt.append(u)
        front = nxt
    return dist


def main(run, scene):
    labels, faces = read_map(run + "/material_map.ply")
    truth_faces = json.load(open(scene + "/truth_labels.json"))["face_labels"]
    votes = collections.defaultdict(collections.Counter)
    adj = collections.defaultdict(set)
    for f, corners in enumerate(faces):
        for v in corners:
            votes[v][truth_faces[f]] += 1
            adj[v].update(u for u in corners if u != v)
    truth = {v: c.most_common(1)[0][0] for v, c in votes.items()}
    pairs = collections.Counter((labels[v], t) for v, t in truth.items())
    stands_for = {}
    for (l, t), n in pairs.items():
        if l not in stands_for or n > pairs[(l, stands_for[l])]:
            stands_for[l] = t
    print("vertices per (found label, truth):", dict(sorted(pairs.items())))
    wrong = [v for v, t in truth.items() if stands_for.get(labels[v]) != t]
    dist = rings(adj, labels)
    hist = collections.Counter(dist.get(v, -1) for v in wrong)
    print("mislabelled vertices:", len(wrong))
    print("rings from the labels' boundary: count", dict(sorted(hist.items())))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
