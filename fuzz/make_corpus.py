#!/usr/bin/env python3
"""Writes the seed corpora fuzz/corpus/<harness>/seed-*: small valid (and a
few nearly valid) inputs of every parser, as the tests and the OpenCalib
sample data have them. Inputs the fuzzers found are kept beside them as
finding-* files, which this script leaves alone. Run from any folder."""
import math
import pathlib
import struct

CORPUS = pathlib.Path(__file__).resolve().parent / "corpus"


def write(harness, name, content):
    folder = CORPUS / harness
    folder.mkdir(parents=True, exist_ok=True)
    data = content.encode() if isinstance(content, str) else content
    (folder / ("seed-" + name)).write_bytes(data)


# ---- rig.yaml ----
RIG = """format: scenecal-dataset/1
base_frame: left
cameras:
  left:
    width: 1280
    height: 960
    model: pinhole
    intrinsics: [983.044, 983.044, 643.647, 493.379]
    distortion: []
    T_base_camera: [0, 0, 0, 0, 0, 0]
  right:
    width: 1280
    height: 960
    model: radtan
    intrinsics: [983.044, 983.044, 643.647, 493.379]
    distortion: [-0.1, 0.01, 0.001, 0.002, 0.0001]
    T_base_camera: [0.24, 0, 0, 0, 0, 0]
    T_base_camera_sigma: [0.0005, 0.0005, 0.0005, 0.001, 0.001, 0.001]
lidars:
  rear:
    kind: 2d
    T_base_lidar: [-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]
"""
write("fuzz_rig", "stereo.yaml", RIG)
write("fuzz_rig", "trajectory_source.yaml", RIG + "trajectory_source: visual-odometry\n")
write("fuzz_rig", "fisheye_matrix.yaml", """format: scenecal-dataset/1
base_frame: cam0
cameras:
  cam0:
    width: 640
    height: 480
    model: equidistant
    intrinsics: [300, 300, 320, 240]
    distortion: [0.01, -0.002, 0.0003, -0.00004]
    T_base_camera: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
lidars:
  top:
    kind: 3d
    T_base_lidar: [[0, -1, 0, 0.1], [0, 0, -1, -0.2], [1, 0, 0, 0.05], [0, 0, 0, 1]]
extra:
  source: kitti
  frames: [0, 10]
""")
write("fuzz_rig", "bad_nan.yaml", RIG.replace("983.044, 643.647", ".nan, 643.647", 1))
write("fuzz_rig", "bad_anchor.yaml", """format: scenecal-dataset/1
base_frame: a
cameras:
  a: &cam {width: 10, height: 10, model: pinhole, intrinsics: [5, 5, 5, 5], distortion: [], T_base_camera: [0, 0, 0, 0, 0, 0]}
  b: *cam
lidars: {l: {kind: 3d, T_base_lidar: [1, 2, 3, 0.1, 0.2, 0.3]}}
""")

# ---- trajectory.csv ----
write("fuzz_trajectory", "rows.csv", "timestamp_us,x,y,z,qx,qy,qz,qw\n"
      "1418381798086398,0.0,0.0,0.0,0.0,0.0,0.0,1.0\n"
      "1418381798136398,0.5,0.01,-0.002,0.0,0.0,0.0499792,0.9987503\n"
      "1418381798186398,1.0,0.02,-0.004,0.001,-0.002,0.0998334,0.9950042\n")
write("fuzz_trajectory", "single_crlf.csv", "timestamp_us,x,y,z,qx,qy,qz,qw\r\n-5,1e3,-2.5e-3,0,0,0,1,0\r\n\r\n")
write("fuzz_trajectory", "bad_inf.csv", "timestamp_us,x,y,z,qx,qy,qz,qw\n0,inf,0,0,0,0,0,1\n")

# ---- ground_truth.yaml ----
write("fuzz_ground_truth", "truth.yaml", """format: scenecal-ground-truth/1
lidars:
  rear:
    T_base_lidar: [-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]
cameras:
  right:
    T_base_camera: [[1, 0, 0, 0.24], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
""")
write("fuzz_ground_truth", "lidars_only.yaml",
      "format: scenecal-ground-truth/1\nlidars: {front: {T_base_lidar: [1, 0, 0.5, 0, 0, 3.14]}}\n")

# ---- calibration result ----
write("fuzz_calibration_result", "result.yaml", """format: scenecal-calibration/1
lidars:
  rear:
    T_base_lidar: [-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]
    sigma: [0.01, 0.01, 0.02, 0.001, 0.001, 0.002]
  front:
    T_base_lidar: [[1, 0, 0, 1.5], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]]
pairs:
  - camera: left
    lidar: rear
    T_camera_lidar: [0.1, 0.2, 0.3, 0.01, 0.02, 0.03]
    cost: 0.912
  - camera: right
    lidar: front
    T_camera_lidar: [0, 0, 0, 0, 0, 0]
    cost: .nan
termination: "converged (cost change below 1e-6)"
settings:
  scheme: "alt"
  threads: "2"
timings_s:
  total: 12.5
  scenes: 1.25
warnings:
  - "lidar front: few points in view"
history:
  - {iteration: 1, cost: 0.95}
""")
write("fuzz_calibration_result", "minimal.yaml", "format: scenecal-calibration/1\nlidars: {}\npairs: []\n")

# ---- option files (--config) and presets ----
for preset in sorted((CORPUS.parent.parent / "config").glob("*.yaml")):
    write("fuzz_option_file", "preset-" + preset.name, preset.read_text())
write("fuzz_option_file", "result.yaml", """format: scenecal-calibration/1
lidars: {}
options:
  scheme: joint
  stages: 1,0.3
  motion-correction: [turn, drive-scale]
  no-uncertainty: true
""")
write("fuzz_option_file", "duplicate.yaml", "thin: 2\nthin: 3\n")

# ---- lidar scans (.bin): float32 x, y, z, reflectance ----
points = [(1.0, 2.0, 3.0, 0.5), (-4.5, 0.25, 1e-3, 1.0), (float("nan"), 0, 0, 0), (10.0, -1.0, 0.0, float("inf"))]
write("fuzz_scan", "four.bin", b"".join(struct.pack("<4f", *p) for p in points))
write("fuzz_scan", "empty.bin", b"")
write("fuzz_scan", "ragged.bin", struct.pack("<4f", 1, 2, 3, 4) + b"\x00\x01\x02")

# ---- PCD ----
def pcd_header(fields, sizes, types, counts, n, encoding, width=None):
    width = n if width is None else width
    return ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
            f"FIELDS {' '.join(fields)}\nSIZE {' '.join(map(str, sizes))}\nTYPE {' '.join(types)}\n"
            f"COUNT {' '.join(map(str, counts))}\nWIDTH {width}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            f"POINTS {n}\nDATA {encoding}\n")

cloud = [(1.0, 2.0, 3.0, 10.0, 7, 0.001 * i + 1e9) for i in range(3)]
fields, sizes, types, counts = ["x", "y", "z", "intensity", "ring", "timestamp"], [4, 4, 4, 4, 2, 8], list("FFFFUF"), [1] * 6
fmts = ["<f", "<f", "<f", "<f", "<H", "<d"]
write("fuzz_pcd", "ascii.pcd", pcd_header(fields, sizes, types, counts, 3, "ascii") +
      "".join(" ".join(repr(v) for v in p) + "\n" for p in cloud))
binary = b"".join(b"".join(struct.pack(f, v) for f, v in zip(fmts, p)) for p in cloud)
write("fuzz_pcd", "binary.pcd", pcd_header(fields, sizes, types, counts, 3, "binary").encode() + binary)
field_major = b"".join(b"".join(struct.pack(fmts[f], p[f]) for p in cloud) for f in range(len(fields)))

def lzf_literals(data):  # a valid LZF stream of literal runs only (control byte n: n + 1 bytes follow)
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)

compressed = lzf_literals(field_major)
write("fuzz_pcd", "binary_compressed.pcd", pcd_header(fields, sizes, types, counts, 3, "binary_compressed").encode() +
      struct.pack("<II", len(compressed), len(field_major)) + compressed)
# The OpenCalib sample's header (x y z intensity ring timestamp), two points.
write("fuzz_pcd", "ints_counts.pcd", pcd_header(["x", "y", "z", "rgb", "t"], [8, 8, 8, 1, 4], list("FFFUI"), [1, 1, 1, 3, 1],
                                                2, "ascii") + "1 2 3 4 5 6 7\n-1e3 2.5 nan 0 0 0 -8\n")
write("fuzz_pcd", "huge_claim.pcd", pcd_header(["x", "y", "z"], [4, 4, 4], list("FFF"), [1, 1, 1], 10**12, "binary"))

# ---- OpenCalib calib.txt: the three sample files ----
for index in (1, 2, 3):
    sample = pathlib.Path(f"/work/shared/data/opencalib/{index}/calib.txt")
    if sample.exists():
        write("fuzz_opencalib", f"sample{index}.txt", sample.read_bytes())
write("fuzz_opencalib", "k3_crlf.txt", "K: 1000 0 640 0 1000 360 0 0 1\r\nD: 0.1 -0.01 0 0 0.001\r\n"
      "T: 1 0 0 0.1 0 1 0 0.2 0 0 1 0.3\r\n")

# ---- KITTI ----
R = "7.533745e-03 -9.999714e-01 -6.166020e-04 1.480249e-02 7.280733e-04 -9.998902e-01 9.998621e-01 7.523790e-03 1.480755e-02"
cam = ("calib_time: 09-Jan-2012 13:57:47\ncorner_dist: 9.950000e-02\n"
       "S_00: 1.392000e+03 5.120000e+02\n"
       "R_rect_00: 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01\n")
for i, tx in enumerate((0.0, -3.875744e+02, 4.485728e+01, -3.395242e+02)):
    cam += f"P_rect_0{i}: 7.215377e+02 0.000000e+00 6.095593e+02 {tx:e} 0.000000e+00 7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03\n"
write("fuzz_kitti_cam_to_cam", "calib_cam_to_cam.txt", cam)
write("fuzz_kitti_transform", "calib_velo_to_cam.txt", f"calib_time: 15-Mar-2012 11:37:16\nR: {R}\n"
      "T: -4.069766e-03 -7.631618e-02 -2.717806e-01\ndelta_f: 0.000000e+00 0.000000e+00\n")
write("fuzz_kitti_transform", "calib_imu_to_velo.txt", "calib_time: 25-May-2012 16:47:16\n"
      "R: 9.999976e-01 7.553071e-04 -2.035826e-03 -7.854027e-04 9.998898e-01 -1.482298e-02 2.024406e-03 1.482454e-02 9.998881e-01\n"
      "T: -8.086759e-01 3.195559e-01 -7.997231e-01\n")
oxts = [49.015003823272, 8.4342971002335, 116.43032836914, 0.035752, 0.00903, -1.2181, -2.1960655471691,
        -10.785111463099, 10.925440182432, 1.0610786646524, 0.16149094148911, -0.39072763919258, 0.67373707801402,
        9.740880608207, -0.49648416600323, 0.24744045364131, 9.779036315286, -0.0065811535156244, 0.014101700282617,
        -0.016366213845038, -0.0066287201567961, 0.013850908493217, -0.016437453046567, 0.40583783388138,
        0.37536916136742, 4, 10, 4, 4, 0]
write("fuzz_kitti_oxts", "record.txt", " ".join(repr(v) for v in oxts) + "\n")
write("fuzz_kitti_oxts", "south_west.txt", " ".join(repr(-v if i < 2 else v) for i, v in enumerate(oxts)))
write("fuzz_kitti_timestamps", "stamps.txt", "2011-09-26 13:02:25.964389445\n2011-09-26 13:02:26.067888334\n\n"
      "2011-09-26 13:02:26.275000000\n2011-09-26 13:02:26.3\n2011-09-26 13:02:27\n")
write("fuzz_kitti_timestamps", "leap.txt", "2012-02-29 23:59:59.999999999\r\n2200-12-31 23:59:59.999999500\n")
print("corpus written to", CORPUS)
