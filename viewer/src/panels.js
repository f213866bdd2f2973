// The side panels (contract; implemented in their own change):
//   createSummary(el, meta) -> {}
//   createFindings(el, meta, {onSelect(finding, index)}) -> {select(index)}
export function createSummary(el, meta) {
  return {};
}

export function createFindings(el, meta, { onSelect }) {
  return { select(index) {} };
}
