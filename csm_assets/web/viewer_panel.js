// viewer_panel.js: the part of the viewer page both engines' viewers share (viewer.js: three.js,
// viewer_babylon.js: Babylon.js): the panel (material, variant and steps switch offering only the
// variants that can draw the selected material's step map, the debug views, the settings shown,
// the status line) and window.csmViewer's engine-free calls.

import { DEBUG, VARIANTS, mapRefusal } from './csm_settings.js';

const $ = (id) => document.getElementById(id);

export function status(text, bad = false) {
	$('status').textContent = text;
	$('status').style.color = bad ? '#f66' : '#fc6';
}

// A debug view's number; an Error for a name DEBUG has not (never a prototype's property).
export function debugView(name) {
	if (!Object.hasOwn(DEBUG, name)) throw new Error(`unknown debug view ${name}; known: off,${Object.keys(DEBUG)}`);
	return DEBUG[name];
}

// The panel over an engine: { settingsOf(material): its CSM settings (variant, steps, quadrant,
// extension, fallback, and uniforms: null on the fallback); setVariant(material, variant, steps);
// setDebug(view, relief on); draw() }. Returns { setMaterials(list, warnings): the page's ready
// answer, api: the engine-free part of window.csmViewer }.
export function makePanel(engine) {
	let materials = [];  // the CSM materials, in glTF order
	const selected = () => ($('material').value === 'all' ? materials : [materials[Number($('material').value)]]);
	const refusal = (m, variant) => mapRefusal(m.name, engine.settingsOf(m).quadrant, variant);
	for (const v of Object.keys(VARIANTS)) $('variant').add(new Option(v, v));

	function showSettings() {
		const m = selected()[0];
		if (!m) { $('settings').textContent = 'no material carries EXT_materials_cone_step_mapping'; return; }
		const csm = engine.settingsOf(m);
		// only the variants that can draw a selected material's step map (a quadrant map: quadrant
		// alone; a one-image map: all but quadrant); the others are greyed, their title says why
		for (const o of $('variant').options) {
			const why = selected().map((x) => refusal(x, o.value));
			o.disabled = why.every(Boolean);
			o.title = o.disabled ? why[0] : '';
		}
		$('variant').value = csm.variant;
		$('steps').value = csm.steps;
		const extra = csm.fallback ? `\nfallback: ${csm.fallback}` : '';
		$('settings').textContent = `${m.name || '(unnamed)'}\n${JSON.stringify(csm.extension, null, 1)}${extra}`;
	}

	function setDebug(name) {
		engine.setDebug(name === 'off' ? DEBUG.lit : debugView(name), name !== 'off');
		engine.draw();
	}

	// Switch `list` to `variant` (null: each keeps its own) with `steps`; a material whose step map
	// the variant cannot draw keeps its own (refused: why). Unknown variants throw.
	function switchVariant(list, variant, steps) {
		const switched = [], refused = [];
		for (const m of list) {
			const csm = engine.settingsOf(m);
			if (!csm.uniforms) continue;  // on the PBR fallback: nothing to switch
			const v = variant ?? csm.variant;
			const why = refusal(m, v);
			if (why) { refused.push(why); continue; }
			engine.setVariant(m, v, steps);
			switched.push(m.name);
		}
		engine.draw();
		return { switched, refused };
	}

	const applyVariant = (variant) => {
		const { refused } = switchVariant(selected(), variant, Number($('steps').value) || 0);
		showSettings();
		if (refused.length) status(`kept their variant: ${refused.join('; ')}`, true);
	};
	$('material').addEventListener('change', showSettings);
	$('debug').addEventListener('change', () => setDebug($('debug').value));
	$('variant').addEventListener('change', () => applyVariant($('variant').value));
	$('steps').addEventListener('change', () => applyVariant(null));

	return {
		setMaterials(list, warnings) {
			materials = list;
			$('material').add(new Option('all materials', 'all'));
			materials.forEach((m, i) => $('material').add(new Option(m.name || `material ${i}`, String(i))));
			showSettings();
			const fallbacks = materials.filter((m) => engine.settingsOf(m).fallback).length;
			status(`${materials.length} CSM material(s)${fallbacks ? `, ${fallbacks} on the PBR fallback` : ''}`);
			return {
				materials: materials.map((m) => {
					const c = engine.settingsOf(m);
					return { name: m.name, variant: c.variant, steps: c.steps, fallback: c.fallback, extension: c.extension };
				}),
				warnings,
			};
		},
		api: {
			setDebug: (name) => { setDebug(name); $('debug').value = name; },
			// every material the variant can draw (the others keep theirs): { switched: names, refused: whys }
			setVariant: (variant, steps = 0) => {
				if (!Object.hasOwn(VARIANTS, variant)) throw new Error(`unknown variant ${variant}; known: ${Object.keys(VARIANTS)}`);
				return switchVariant(materials, variant, steps);
			},
			materials: () => materials,
			showPanel: (on) => { $('panel').style.display = on ? '' : 'none'; },
		},
	};
}

// The page's ready promise: start() resolved, or { error } (shown in the status line).
export function starting(start) {
	return start().catch((e) => {
		status(`error: ${e.message || e}`, true);
		return { error: String(e.message || e) };
	});
}
