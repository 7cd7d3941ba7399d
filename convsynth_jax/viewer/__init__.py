"""The 3D motion viewer in the browser (``task=view``): a scene of joint positions computed in Python
(:mod:`.scene`), a Starlette application serving it on loopback and a static export that opens from
the file system (:mod:`.server`), the page's script (``static/viewer.js``) and the vendored three.js
(``static/vendor/``). docs/viewer.md."""
