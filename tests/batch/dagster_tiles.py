#!/usr/bin/env python3
"""The Dagster example (examples/jobs/dagster) materialised in-process on a temporary instance:
`tile_plan`, every partition of `city_tile` one run each, then `merged_city`.

usage: dagster_tiles.py --blockwalk BIN --city CITY [--streets FILE] --out DIR --max-buildings N

Before the plan that counts, a plan with N // 2 buildings per tile (more tiles) registers its
partitions: the second plan must replace them, leaving exactly its own. Checks that the
partitions are the plan's tiles, that every partition was materialised once with the figures of
its tile's manifest, and that the merged asset's figures are the sums. Prints one JSON object:
{"out": DIR, "tiles": N, "runs": runs}.
"""

import argparse
import importlib.util
import json
import sys
from pathlib import Path

import dagster as dg

EXAMPLE = Path(__file__).resolve().parents[2] / "examples/jobs/dagster/blockwalk_tiles.py"


def fail(why):
    print(f"dagster_tiles: {why}", file=sys.stderr)
    sys.exit(1)


def metadata(result, asset):
    (m,) = result.asset_materializations_for_node(asset)
    return {k: v.value for k, v in m.metadata.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--blockwalk", required=True)
    ap.add_argument("--city", required=True)
    ap.add_argument("--streets", default="")
    ap.add_argument("--out", required=True)
    ap.add_argument("--max-buildings", type=int, required=True)
    a = ap.parse_args()

    spec = importlib.util.spec_from_file_location("blockwalk_tiles", EXAMPLE)
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)

    def resource(max_buildings):
        return {
            "blockwalk": ex.Blockwalk(
                binary=a.blockwalk, city=a.city, streets=a.streets, out=a.out, max_buildings=max_buildings
            )
        }

    runs = 0
    with dg.DagsterInstance.ephemeral() as inst:

        def materialize(selection, res, key=None):
            nonlocal runs
            runs += 1
            r = dg.materialize(ex.ASSETS, selection=selection, partition_key=key, instance=inst, resources=res)
            if not r.success:
                fail(f"materialising {selection} {key or ''} failed")
            return r

        # A first plan of smaller tiles, then the one that counts: its partitions replace the first's.
        first = metadata(materialize([ex.tile_plan], resource(a.max_buildings // 2)), "tile_plan")
        res = resource(a.max_buildings)
        plan_meta = metadata(materialize([ex.tile_plan], res), "tile_plan")
        plan = json.loads((Path(a.out) / "plan.json").read_text())
        n = len(plan["tiles"])
        if not first["tiles"] > n >= 4:
            fail(f"the plans have {first['tiles']} and {n} tiles: a test of at least 4, fewer the second time")
        keys = inst.get_dynamic_partitions(ex.TILES.name)
        if sorted(keys, key=int) != [str(i) for i in range(n)]:
            fail(f"partitions {keys} for a plan of {n} tiles")
        if plan_meta["plan_id"] != plan["plan_id"] or plan_meta["tiles"] != n:
            fail(f"tile_plan's metadata {plan_meta} is not plan.json's")

        sums = {"blocks": 0, "buildings": 0, "triangles": 0}
        for k in keys:
            m = metadata(materialize([ex.city_tile], res, key=k), "city_tile")
            manifest = json.loads((Path(a.out) / "tiles" / f"tile_{int(k):05}.json").read_text())
            if (m["buildings"], m["triangles"], m["plan_id"]) != (
                manifest["buildings"],
                manifest["triangles"],
                plan["plan_id"],
            ):
                fail(f"partition {k}: metadata {m}, manifest of tile {manifest['tile']}")
            for s in sums:
                sums[s] += m[s]
        done = inst.get_materialized_partitions(dg.AssetKey("city_tile"))
        if done != set(keys):
            fail(f"materialised partitions {sorted(done)}, the plan's {keys}")

        merged = metadata(materialize([ex.merged_city], res), "merged_city")
        if merged["tiles"] != n or any(merged[s] != v for s, v in sums.items()):
            fail(f"merged_city's metadata {merged}; the tiles sum to {sums} in {n} tiles")
        if merged["buildings"] != plan["buildings"]:
            fail(f"{merged['buildings']} buildings merged, the plan has {plan['buildings']}")
    print(json.dumps({"out": a.out, "tiles": n, "runs": runs}))


if __name__ == "__main__":
    main()
