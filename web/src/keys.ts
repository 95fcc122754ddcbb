// The desktop viewer's keys: F2 the statistics, F3 the 2x2 layout, F4 the
// patient (wherever the keyboard is: no field types them); and, outside the
// fields, A P L R S I the named views, Home or Space the first view.
import type { ViewName } from "./navigation.js";

const KEY_VIEWS: Record<string, ViewName> = {
  a: "ANTERIOR", p: "POSTERIOR", l: "LEFT", r: "RIGHT", s: "SUPERIOR", i: "INFERIOR",
};

export interface KeyActions {
  statistics(): void;  // F2
  layout(): void;      // F3
  identity(): void;    // F4
  home(): void;
  namedView(view: ViewName): void;
}

export function listenToKeys(actions: KeyActions): void {
  window.addEventListener("keydown", (e) => {
    if (functionKey(e.key, actions)) return e.preventDefault();
    const target = e.target as HTMLElement;
    if (target.matches("input:not([type=checkbox]):not([type=range]), select, textarea")) return;
    const view = KEY_VIEWS[e.key.toLowerCase()];
    if (e.key === "Home" || e.key === " ") actions.home();
    else if (!e.ctrlKey && !e.altKey && !e.metaKey && view !== undefined) actions.namedView(view);
    else return;
    e.preventDefault();
  });
}

/** F2, F3 and F4; false for any other key. */
function functionKey(key: string, actions: KeyActions): boolean {
  if (key === "F2") actions.statistics();
  else if (key === "F3") actions.layout();
  else if (key === "F4") actions.identity();
  else return false;
  return true;
}
