// Renders Studio's App with in-memory settings and the layout r2d2_sim ships
// (resource/foxglove_layout.json, served as /layout.json) as the current one.
"use strict";

(async function main() {
  const LAYOUT_ID = "r2d2_sim";
  const layoutData = await (await fetch("/layout.json")).json();
  const savedAt = new Date().toISOString();
  const layouts = new Map([[LAYOUT_ID, {
    id: LAYOUT_ID, name: "r2d2_sim", permission: "CREATOR_WRITE",
    baseline: { data: layoutData, savedAt }, working: undefined, syncInfo: undefined,
  }]]);
  const layoutStorage = {
    async list() { return [...layouts.values()]; },
    async get(namespace, id) { return layouts.get(id); },
    async put(namespace, layout) { layouts.set(layout.id, layout); return layout; },
    async delete(namespace, id) { layouts.delete(id); },
    async importLayouts() {},
    async migrateUnnamespacedLayouts() {},
  };

  const settings = new Map([["telemetry.telemetryEnabled", false],
                            ["telemetry.crashReportingEnabled", false]]);
  const listeners = new Map();
  const appConfiguration = {
    get: (key) => settings.get(key),
    async set(key, value) {
      settings.set(key, value);
      for (const listener of listeners.get(key) ?? []) { listener(value); }
    },
    addChangeListener(key, listener) {
      listeners.set(key, [...(listeners.get(key) ?? []), listener]);
    },
    removeChangeListener(key, listener) {
      listeners.set(key, (listeners.get(key) ?? []).filter((l) => l !== listener));
    },
  };
  localStorage.setItem("studio.profile-data", JSON.stringify({ currentLayoutId: LAYOUT_ID }));

  await window.initI18n();
  const dataSources = [
    new window.FoxgloveWebSocketDataSourceFactory(),
    new window.RemoteDataSourceFactory(),
    new window.McapLocalDataSourceFactory(),
  ];
  window.ReactDOM.render(
    window.React.createElement(window.App, {
      deepLinks: [window.location.href],
      appConfiguration,
      dataSources,
      layoutStorage,
      extensionLoaders: [],
      enableLaunchPreferenceScreen: false,
      enableGlobalCss: true,
    }),
    document.getElementById("root"));
  window.r2d2HostReady = true;
})().catch((error) => {
  window.r2d2HostError = String(error && error.stack || error);
  console.error(error);
});
