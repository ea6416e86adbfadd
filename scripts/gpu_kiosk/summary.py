"""One kiosk run's report.json in a few lines (run_on_device.sh): frame times, tasks, method,
stitching, memory and recovery. Usage: summary.py NAME REPORT_JSON"""
import json, sys
name, path = sys.argv[1], sys.argv[2]
try:
    r = json.load(open(path))
except Exception as e:
    print(name, "no report", e); sys.exit()
ms = lambda v: round(v / 1e3, 2)
def pct(t):
    return "p50 %.2f p90 %.2f p99 %.2f max %.2f miss %d/%d" % (ms(t['p50_us']), ms(t['p90_us']), ms(t['p99_us']), ms(t['max_us']), t['deadline_misses'], t['count'])
print("==", name, "renderer:", r.get('renderer'), "frames", r.get('frames'), "threads", r.get('threads'))
print("  frame", pct(r['frame_time']))
print("  capped", pct(r['frame_time_render_capped']))
for k, v in r['tasks'].items():
    print("  task", k, pct(v['time']), "budget", ms(v['time']['budget_us']), "slips", v.get('slips'), "overruns", v.get('overruns'))
for m, t in r.get('frame_time_by_method', {}).items():
    print("  by method", m, pct(t))
s = r.get('sim', {}); st = r.get('stitching', {})
print("  sim", {k: s[k] for k in s if not isinstance(s[k], (list, dict))})
print("  stitching", {k: st[k] for k in st if not isinstance(st[k], (list, dict))})
print("  memory", {k: r['memory'][k] for k in r.get('memory', {}) if not isinstance(r['memory'][k], (list, dict))})
print("  recovery", r.get('recovery_events') if not isinstance(r.get('recovery_events'), list) else len(r['recovery_events']))
