#!/usr/bin/env python3
"""Operon's figures for the scoreboard (bench/scoreboard, `--operon`), from peer results.

    python3 bench/peer/board_operon.py RESULTS.json [RESULTS.json ...] -o operon.json

Reads the results.json files of bench/peer/run.py and writes, per scoreboard table and error
channel, Operon's best held-out RMS and best held-out max |error| at ISA <= k (measured RDNA2
instructions) for every k where its front has a member, taking every seed of every file
(the best over seeds: the figure most favourable to Operon). Members whose translation check
failed are left out. The peer's DFG channels map to the board's `dfg` table (channels F0=1 and
F0=0.04: a renderer with a fixed F0 ships one such formula); any other peer table keeps its name
and has a single channel. The per-output runs of a table with several outputs (`zh_ZH0`, ...)
keep theirs too, so the board does not show them: it costs one program for all the outputs a
shader needs, and one Operon model per output, each at ISA <= k, is not that.
"""
import argparse
import json
import math
import sys

# peer table -> (board table, board channel or None for a single-channel table)
BOARD = {"dfg_f0_1": ("dfg", "F0=1"), "dfg_f0_0p04": ("dfg", "F0=0.04")}


def entries(results_list):
    """{board table: [{"channel"?, "isa_max", "rmse", "max_abs"}]} from peer results."""
    members = {}  # (table, channel) -> [(isa, rms, max)]
    for res in results_list:
        for run in res.get("runs", []):
            key = BOARD.get(run["table"], (run["table"], None))
            for m in run.get("operon", {}).get("members", []):
                if m.get("check") is False:
                    continue
                isa, rms, mx = m.get("isa"), m.get("heldout_rms"), m.get("heldout_max")
                if all(isinstance(v, (int, float)) and math.isfinite(v) for v in (isa, rms, mx)):
                    members.setdefault(key, []).append((isa, rms, mx))
    out = {}
    for (table, channel), ms in sorted(members.items()):
        best_rms = best_max = math.inf
        for k in sorted({isa for isa, _, _ in ms}):
            best_rms = min([best_rms] + [r for i, r, _ in ms if i <= k])
            best_max = min([best_max] + [x for i, _, x in ms if i <= k])
            e = {"isa_max": k, "rmse": best_rms, "max_abs": best_max}
            if channel is not None:
                e["channel"] = channel
            out.setdefault(table, []).append(e)
    return {"tables": out}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+", help="results.json of bench/peer/run.py")
    ap.add_argument("-o", "--out", required=True, help="the board's operon.json")
    args = ap.parse_args(argv)
    loaded = []
    for path in args.results:
        try:
            with open(path) as f:
                loaded.append(json.load(f))
        except (OSError, ValueError) as e:
            sys.exit("board_operon: %s: %s" % (path, e))
    board = entries(loaded)
    if not board["tables"]:
        sys.exit("board_operon: no Operon member with a measured ISA and held-out figures")
    with open(args.out, "w") as f:
        json.dump(board, f, indent=1)
        f.write("\n")
    for t, es in board["tables"].items():
        print("%s: %d entries" % (t, len(es)))


if __name__ == "__main__":
    main()
