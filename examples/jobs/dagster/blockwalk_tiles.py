"""A city in tiles as Dagster assets: `tile_plan` runs `blockwalk jobs plan` and registers one
dynamic partition per tile; `city_tile`, partitioned by tile, runs `blockwalk jobs run --tile I`
for its partition; `merged_city`, which depends on every partition of `city_tile`, runs
`blockwalk jobs merge`. Each asset's materialisation carries the step's figures as metadata.

Load it with `dagster dev -f examples/jobs/dagster/blockwalk_tiles.py` after setting

    BLOCKWALK                the binary (default: `blockwalk` on PATH)
    BLOCKWALK_CITY           a generated city's folder, or a footprint .shp with BLOCKWALK_STREETS
    BLOCKWALK_STREETS        street centre lines (when BLOCKWALK_CITY is a file)
    BLOCKWALK_OUT            the plan's folder
    BLOCKWALK_MAX_BUILDINGS  buildings per tile (default 50000)

then materialise `tile_plan`, then every partition of `city_tile` (a backfill: one run per
partition, as many at once as the run coordinator allows), then `merged_city`. A partition whose
run failed is materialised again alone. A new plan replaces the partitions of the old one.
"""

import json
import os
import subprocess

import dagster as dg

TILES = dg.DynamicPartitionsDefinition(name="blockwalk_tiles")


class Blockwalk(dg.ConfigurableResource):
    """The `blockwalk` binary and the city it cuts into tiles."""

    binary: str = "blockwalk"
    city: str
    streets: str = ""
    out: str
    max_buildings: int = 50_000
    # Options every tile run gets (e.g. ["--blockmaps", "64"]).
    run_options: list[str] = []

    def json(self, *args: str) -> dict:
        """Runs `blockwalk ARGS --json` and returns the JSON object it prints."""
        argv = [self.binary, *args, "--json"]
        p = subprocess.run(argv, capture_output=True, text=True)
        if p.returncode != 0:
            raise dg.Failure(
                description=f"`{' '.join(argv)}` exited {p.returncode}",
                metadata={"stderr": dg.MetadataValue.text(p.stderr)},
            )
        return json.loads(p.stdout)

    @property
    def plan(self) -> str:
        return os.path.join(self.out, "plan.json")


@dg.asset
def tile_plan(context: dg.AssetExecutionContext, blockwalk: Blockwalk) -> dg.MaterializeResult:
    """The plan: the city's blocks cut into tiles; one partition of `city_tile` per tile."""
    args = ["jobs", "plan", blockwalk.city, "-o", blockwalk.out, "--max-buildings", str(blockwalk.max_buildings)]
    if blockwalk.streets:
        args += ["--streets", blockwalk.streets]
    p = blockwalk.json(*args)
    keys = [str(i) for i in range(p["tiles"])]
    stale = [k for k in context.instance.get_dynamic_partitions(TILES.name) if k not in keys]
    for k in stale:
        context.instance.delete_dynamic_partition(TILES.name, k)
    context.instance.add_dynamic_partitions(TILES.name, keys)
    return dg.MaterializeResult(
        metadata={
            "plan": dg.MetadataValue.path(p["plan"]),
            "plan_id": p["plan_id"],
            "tiles": p["tiles"],
            "blocks": p["blocks"],
            "buildings": p["buildings"],
            "largest_tile_buildings": p["max_tile_buildings"],
        }
    )


@dg.asset(partitions_def=TILES, deps=[tile_plan])
def city_tile(context: dg.AssetExecutionContext, blockwalk: Blockwalk) -> dg.MaterializeResult:
    """One tile: its `.glb`, block mesh pack, hierarchy and manifest."""
    m = blockwalk.json("jobs", "run", blockwalk.plan, "--tile", context.partition_key, *blockwalk.run_options)
    return dg.MaterializeResult(
        metadata={
            "plan_id": m["plan_id"],
            "blocks": len(m["blocks"]),
            "buildings": m["buildings"],
            "buildings_read": m["buildings_read"],
            "triangles": m["triangles"],
            "files": len(m["files"]),
            "seconds": m["seconds"],
        }
    )


@dg.asset(deps=[city_tile])
def merged_city(blockwalk: Blockwalk) -> dg.MaterializeResult:
    """Every tile checked and `index.json` written (refused while a tile has not finished)."""
    i = blockwalk.json("jobs", "merge", blockwalk.out)
    return dg.MaterializeResult(
        metadata={
            "index": dg.MetadataValue.path(i["index"]),
            "plan_id": i["plan_id"],
            "tiles": i["tiles"],
            "blocks": i["blocks"],
            "buildings": i["buildings"],
            "triangles": i["triangles"],
            "bytes": i["bytes"],
        }
    )


ASSETS = [tile_plan, city_tile, merged_city]


def resource_from_env() -> Blockwalk:
    """The resource the variables above describe."""
    return Blockwalk(
        binary=os.environ.get("BLOCKWALK", "blockwalk"),
        city=os.environ.get("BLOCKWALK_CITY", ""),
        streets=os.environ.get("BLOCKWALK_STREETS", ""),
        out=os.environ.get("BLOCKWALK_OUT", "out"),
        max_buildings=int(os.environ.get("BLOCKWALK_MAX_BUILDINGS", "50000")),
    )


defs = dg.Definitions(assets=ASSETS, resources={"blockwalk": resource_from_env()})
