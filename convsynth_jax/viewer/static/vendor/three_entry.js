export { WebGLRenderer, Scene, PerspectiveCamera, Color, Fog, HemisphereLight, DirectionalLight, AmbientLight, Mesh, Group,
  CylinderGeometry, SphereGeometry, PlaneGeometry, CircleGeometry, MeshLambertMaterial, MeshBasicMaterial, GridHelper,
  Vector3, Quaternion, Box3, SRGBColorSpace } from 'three';
export { OrbitControls } from 'three/addons/controls/OrbitControls.js';
