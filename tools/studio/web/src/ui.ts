// DOM helpers and the message bar (#message).

import { hooks } from './hooks';

/** The element with this id; throws when index.html lacks it (a build mistake). */
export function byId<T extends HTMLElement = HTMLElement>(id: string): T {
  const element = document.getElementById(id);
  if (!element) throw new Error(`index.html has no #${id}`);
  return element as T;
}

export type MessageKind = 'error' | 'info' | 'ok';

/** Shows a message in #message; `detail` lines are shown below it in a smaller font. */
export function showMessage(kind: MessageKind, text: string, detail: string[] = []): void {
  const box = byId('message');
  box.dataset.kind = kind;
  box.replaceChildren();
  const main = document.createElement('span');
  main.className = 'message-text';
  main.textContent = text;
  box.append(main);
  for (const line of detail) {
    const extra = document.createElement('span');
    extra.className = 'message-detail';
    extra.textContent = line;
    box.append(extra);
  }
  box.hidden = false;
  hooks.lastMessage = [text, ...detail].join('\n');
}

export function setText(id: string, text: string): void {
  byId(id).textContent = text;
}

export function formatNumber(value: number, digits: number): string {
  return Number.isFinite(value) ? value.toFixed(digits) : '-';
}
