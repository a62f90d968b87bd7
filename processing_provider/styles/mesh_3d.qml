<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>
<qgis version="3.22.16-Białowieża" styleCategories="Symbology3D">
  <renderer-3d type="mesh" layer="">
    <symbol type="mesh">
      <data alt-clamping="absolute" height="0" add-back-faces="1"/>
      <material diffuse="178,178,178,255" ambient="26,26,26,255" specular="255,255,255,255" shininess="0" opacity="1">
        <data-defined-properties>
          <Option type="Map">
            <Option name="name" value="" type="QString"/>
            <Option name="properties"/>
            <Option name="type" value="collection" type="QString"/>
          </Option>
        </data-defined-properties>
      </material>
      <advanced-settings renderer-3d-enabled="1" smoothed-triangle="0" wireframe-enabled="0" wireframe-line-width="1" wireframe-line-color="128,128,128,255" level-of-detail="0" vertical-scale="1" vertical-group-index="-1" vertical-relative="0" texture-type="1" min-color-ramp-shader="0" max-color-ramp-shader="0" texture-single-color="0,128,0,255" arrows-enabled="0" arrows-spacing="25" arrows-fixed-size="0">
        <colorrampshader colorRampType="INTERPOLATED" classificationMode="1" clip="0" minimumValue="0" maximumValue="0"/>
      </advanced-settings>
      <data-defined-properties>
        <Option type="Map">
          <Option name="name" value="" type="QString"/>
          <Option name="properties"/>
          <Option name="type" value="collection" type="QString"/>
        </Option>
      </data-defined-properties>
    </symbol>
  </renderer-3d>
</qgis>
