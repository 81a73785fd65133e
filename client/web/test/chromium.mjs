// Launches Debian's Chromium headless through playwright-core (nothing downloaded), with the
// flags this machine needs: no sandbox as root, no GPU (SwiftShader WebGL), no background
// network calls (the network is closed), a fresh profile.
import { chromium } from 'playwright-core';

export const chromiumPath = process.env.CHROMIUM || '/usr/bin/chromium';

export function launchChromium() {
  return chromium.launch({ executablePath: chromiumPath, headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] });
}
