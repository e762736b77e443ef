"""Writes the igd service config the end-to-end host-link tests run with: a tiny paced headless
output, a stats CSV, the default scene (or another), and one live host link.

write_link_config(tmp, source, link_table, link_body, src, rate_hz, frames, link_timeout_s,
                  record_file="", scene="") -> path of tmp/igd.toml, stats in tmp/stats.csv
"""
import os


def write_link_config(tmp, source, link_table, link_body, src, rate_hz, frames, link_timeout_s,
                      record_file="", scene="", extra=""):
    """scene: the scene file ("" = config/scenes/default.toml); extra: more TOML tables, appended."""
    path = os.path.join(tmp, "igd.toml")
    scene = scene or os.path.join(src, 'config/scenes/default.toml')
    record = f'record_file = "{record_file}"\n' if record_file else ""
    with open(path, "w") as f:
        f.write(f"""[frame]
rate_hz = {rate_hz}
frames = {frames}
free_run = false
[output]
mode = "headless"
width_px = 64
height_px = 64
snapshot_every = 0
[stats]
file = "{tmp}/stats.csv"
format = "csv"
[host]
source = "{source}"
link_timeout_s = {link_timeout_s}
{record}[host.{link_table}]
{link_body}
[scene]
file = "{scene}"
{extra}""")
    return path
