// The Gantt chart under the 3D view (contract; implemented in its own change):
//   createGantt(el, meta, {onSeek(t)}) -> {setTime(t)}
// el: a <div> to fill; meta: the page's JSON record (meta.gantt rows, meta.robots colours,
// meta.makespan); onSeek(t) is called when the user clicks a bar or the axis.
export function createGantt(el, meta, { onSeek }) {
  return { setTime(t) {} };
}
