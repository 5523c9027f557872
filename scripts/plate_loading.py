#!/usr/bin/env python3
"""How the rear wall of a 3D `blt sim run` is loaded: per particle frame, the rearward (-z) momentum of the
rear wall's points and how it is spread over the wall's plane.

    scripts/plate_loading.py RUN_DIR [--bin 0.5]

RUN_DIR is the --out folder of a 3D run made with frames (`--set run.frames=24`, not --no-frames). Prints CSV:
time_us, rearward_momentum_mN_s (sum of m |v_z| over the wall's points moving rearward, whole target),
area_50_mm2 and area_90_mm2 (the smallest set of bins that holds 50 % and 90 % of it, whole target),
peak_impulse_mN_s_per_mm2 (the most loaded bin), centroid_x_mm (downrange, along the plane of incidence),
projectile_z_mm and projectile_x_mm (centre of mass of the projectile's points still in the grid; x is 0 in a
quarter model, centred on its symmetry planes).
Used in docs/validation/table7.md to compare an oblique shot with a normal one at the same V cos(theta).
Python 3 standard library only; reads the raw appended VTU that blt writes (libsim/src/output.cpp).
"""
import argparse
import json
import math
import pathlib
import re
import struct
import sys

TYPES = {"Float64": "d", "Int32": "i", "UInt8": "B", "Int64": "q"}


def read_vtu(path):
    data = path.read_bytes()
    head, _, rest = data.partition(b'<AppendedData encoding="raw">')
    blob = rest[rest.index(b"_") + 1:]
    count = int(re.search(rb'NumberOfPoints="(\d+)"', head).group(1))
    fields = {}
    pattern = rb'<DataArray type="(\w+)"(?: Name="(\w+)")? NumberOfComponents="(\d+)" format="appended" offset="(\d+)"'
    for m in re.finditer(pattern, head):
        kind, name, components, offset = m.group(1).decode(), (m.group(2) or b"points").decode(), int(m.group(3)), int(m.group(4))
        size = struct.unpack_from("<Q", blob, offset)[0]
        code = TYPES[kind]
        values = struct.unpack_from("<%d%s" % (size // struct.calcsize(code), code), blob, offset + 8)
        fields[name] = values if components == 1 else [values[i * components:(i + 1) * components] for i in range(count)]
    return count, fields


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=pathlib.Path)
    parser.add_argument("--bin", type=float, default=0.5, help="bin side in the wall's plane, mm (default 0.5)")
    args = parser.parse_args()

    summaries = sorted(args.run_dir.glob("*_summary.json"))
    if not summaries:
        sys.exit("plate_loading: no *_summary.json in %s (the --out folder of blt sim run)" % args.run_dir)
    summary = json.loads(summaries[0].read_text())
    mirror = {"3D half model": 2, "3D quarter model": 4}.get(summary["model"])
    if mirror is None:
        sys.exit("plate_loading: %s is a '%s' run; only 3D half and quarter models are read" % (summaries[0], summary["model"]))
    wall_body = len(summary["layers"])  # body 0 is the projectile, then the layers front to rear
    name = summaries[0].name[: -len("_summary.json")]
    pvd = args.run_dir / (name + ".pvd")
    if not pvd.exists():
        sys.exit("plate_loading: %s is missing: run with frames (not --no-frames)" % pvd)
    frames = re.findall(r'timestep="([^"]+)"[^>]*file="([^"]+)"', pvd.read_text())

    side = args.bin * 1e-3
    print("time_us,rearward_momentum_mN_s,area_50_mm2,area_90_mm2,peak_impulse_mN_s_per_mm2,centroid_x_mm,"
          "projectile_z_mm,projectile_x_mm")
    for time, file in frames:
        count, f = read_vtu(args.run_dir / file)
        bins, total, moment = {}, 0.0, 0.0
        projectile_mass = projectile_z = projectile_x = 0.0
        for i in range(count):
            if not f["active"][i]:
                continue
            x, m = f["points"][i], f["mass_kg"][i]
            if f["body"][i] == 0:
                projectile_mass += m
                projectile_z += m * x[2]
                projectile_x += m * x[0]
            vz = f["velocity_m_s"][i][2]
            if f["body"][i] != wall_body or vz >= 0:
                continue
            p = -m * vz
            key = (math.floor(x[0] / side), math.floor(x[1] / side))
            bins[key] = bins.get(key, 0.0) + p
            total += p
            moment += p * x[0]
        row = [float(time) * 1e6, total * mirror * 1e3]
        if total * mirror > 1e-9:  # below a nanonewton-second the wall has not been reached; areas mean nothing
            loads = sorted(bins.values(), reverse=True)
            areas, held, targets = [], 0.0, [0.5, 0.9]
            for k, b in enumerate(loads):
                held += b
                while targets and held >= targets[0] * total:
                    areas.append((k + 1) * args.bin ** 2 * mirror)
                    targets.pop(0)
            # A quarter model's centroid sits on its symmetry planes by construction.
            row += areas + [loads[0] * 1e3 / args.bin ** 2, moment / total * 1e3 if mirror == 2 else 0.0]
        else:
            row += [0.0, 0.0, 0.0, 0.0]
        if projectile_mass > 0:
            row += [projectile_z / projectile_mass * 1e3, projectile_x / projectile_mass * 1e3 if mirror == 2 else 0.0]
        else:
            row += [float("nan"), float("nan")]
        print(",".join("%.4g" % v for v in row))


if __name__ == "__main__":
    main()
